"""Without ROS: ``pip install .`` alone runs the research commands.

In a venv of its own, made from this checkout with setup.py's install_requires and nothing else
(no ros-jazzy wheels, no numba, no ROS share directory, no PYTHONPATH): ``mta check`` of a scene
named as users name it, ``mta run`` of it into a bag, ``mta analyze`` and ``mta replay
--resimulate`` of that bag, and a benchmark that needs no DDS (``python -m benchmarks tick-parts``, whose
parser also imports every benchmark module). The test first shows that ``import rclpy`` fails
there, so it proves what it claims. test_rooms.py runs the same commands in this environment with
the ROS imports blocked; this one shows what such an install lacks besides: the ROS share
directories (the bag's schemas come from the package's own copies of the .msg files, and are
held here to the installed ones byte for byte), an editable checkout (the config files come from
setup.py's data_files).

The venv is kept in pytest's cache (``.pytest_cache``) between runs, rebuilt when setup.py
changes, the package reinstalled when any of its files do. pip downloads from PyPI what its cache
lacks; where it cannot, the test fails and says so (it is never skipped).
"""
from __future__ import annotations

import fcntl
import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader

from mta_sim_ros.bag import message_definition

pytestmark = pytest.mark.slow  # a venv built and filled by pip

REPO = Path(__file__).resolve().parents[1]
#: what `pip install .` needs of the checkout (setup.py reads package.xml, resource/, config/)
SOURCES = ("setup.py", "setup.cfg", "package.xml", "resource", "config", "mta_sim_ros")
IGNORED = shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc", "*.egg-info")
SCENE = "scenes/lane_change.yaml"  # a name, resolved in the install's own config folder
PIP_TIMEOUT = 1800


def digest(paths) -> str:
    """sha256 over the files below ``paths`` (relative to the checkout), names and contents."""
    h = hashlib.sha256()
    for rel in paths:
        root = REPO / rel
        files = [root] if root.is_file() else sorted(p for p in root.rglob("*") if p.is_file())
        for path in files:
            if path.suffix in (".pyc", ".nbi", ".nbc") or "__pycache__" in path.parts:
                continue
            h.update(str(path.relative_to(REPO)).encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


def clean_env(home: Path) -> dict[str, str]:
    """This environment without what would bring ROS or this checkout into a child: no
    PYTHONPATH, no ROS prefix, no library path of the ROS wheels (their bootstrapper's marker
    removed too), no active venv."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP", "VIRTUAL_ENV", "AMENT_PREFIX_PATH",
                        "CMAKE_PREFIX_PATH", "LD_LIBRARY_PATH", "_ROS_WHEELS_BOOTSTRAP_COMPLETE", "NUMBA_CACHE_DIR")}
    env.update(HOME=str(home), MPLBACKEND="Agg", MPLCONFIGDIR=str(home / "mpl"), PIP_NO_INPUT="1",
               PIP_DISABLE_PIP_VERSION_CHECK="1", PYTHONDONTWRITEBYTECODE="1")
    return env


def base_python() -> Path:
    """The interpreter this suite's venv was made from (same version), outside any venv."""
    name = f"python{sys.version_info.major}.{sys.version_info.minor}"
    for candidate in (Path(sys.base_prefix) / "bin" / name, shutil.which(name)):
        if candidate and Path(candidate).is_file():
            return Path(candidate)
    pytest.fail(f"{name} not found (looked in {sys.base_prefix}/bin and on PATH): the venv without ROS needs it")


def pip(venv: Path, env: dict[str, str], *args: str) -> None:
    cmd = [str(venv / "bin" / "python"), "-m", "pip", "install", "-q", *args]
    try:
        done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=PIP_TIMEOUT,
                              stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        pytest.fail(f"pip install did not finish in {PIP_TIMEOUT} s (is PyPI reachable?): {' '.join(cmd)}")
    if done.returncode != 0:
        pytest.fail(f"pip could not build the venv without ROS (it downloads from PyPI what pip's cache "
                    f"lacks; is PyPI reachable?): {' '.join(cmd)} exited {done.returncode}:\n"
                    f"{done.stdout[-2000:]}\n{done.stderr[-4000:]}", pytrace=False)


@pytest.fixture(scope="module")
def noros(request, tmp_path_factory):
    """(venv, env): the venv without ROS, built or brought up to date under a lock."""
    cache = Path(request.config.cache.mkdir("venv-noros"))
    venv, stamp = cache / "venv", cache / "stamp.json"
    home = tmp_path_factory.mktemp("home")
    env = clean_env(home)
    want = {"python": sys.version, "setup": digest(("setup.py", "setup.cfg")), "package": digest(SOURCES)}
    with open(cache / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # another suite running at once waits for this build
        have = json.loads(stamp.read_text()) if stamp.is_file() else {}
        if have != want:
            stamp.unlink(missing_ok=True)
            src = tmp_path_factory.mktemp("src")
            for rel in SOURCES:
                (shutil.copytree(REPO / rel, src / rel, ignore=IGNORED) if (REPO / rel).is_dir()
                 else shutil.copy2(REPO / rel, src / rel))
            if have.get("python") != want["python"] or have.get("setup") != want["setup"] or not venv.is_dir():
                shutil.rmtree(venv, ignore_errors=True)
                subprocess.run([str(base_python()), "-m", "venv", str(venv)], env=env, check=True, timeout=300)
                pip(venv, env, str(src))
            else:  # the same dependencies: the package alone
                pip(venv, env, "--no-deps", "--force-reinstall", str(src))
            stamp.write_text(json.dumps(want))
    return venv, env


def run(noros, cwd: Path, *args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    venv, env = noros
    exe = [str(venv / "bin" / args[0]), *args[1:]]
    return subprocess.run(exe, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout,
                          stdin=subprocess.DEVNULL)


def test_there_is_no_ros_in_that_venv(noros, tmp_path):
    venv, _ = noros
    done = run(noros, tmp_path, "python", "-c", "import rclpy")
    assert done.returncode != 0 and "No module named 'rclpy'" in done.stderr, done.stderr
    probe = ("import json, mta_sim_ros, mta_sim_ros.bag.schemas as s; from mta_sim_ros import jit\n"
             "print(json.dumps([mta_sim_ros.__file__, [str(d) for d in s.share_dirs()], jit.ENABLED]))")
    done = run(noros, tmp_path, "python", "-c", probe)
    assert done.returncode == 0, done.stderr
    where, shares, jit = json.loads(done.stdout)
    assert Path(where).is_relative_to(venv), f"mta_sim_ros imported from {where}, not the venv's install"
    assert not any((Path(d) / "std_msgs").exists() for d in shares), shares  # no ROS share dir
    assert jit is False  # numba is the 'jit' extra, not installed: the Python path runs


def test_the_research_commands_run_from_a_plain_pip_install(noros, tmp_path):
    done = run(noros, tmp_path, "mta", "check", SCENE)
    assert done.returncode == 0, done.stderr

    bag = tmp_path / "run.mcap"
    done = run(noros, tmp_path, "mta", "run", "--scene", SCENE, "--bag", str(bag), "--quiet")
    assert done.returncode == 0, done.stderr
    with open(bag, "rb") as f:
        summary = make_reader(f).get_summary()
    # the vendored .msg files make the schemas a ROS install makes (this suite runs with ROS)
    assert {s.name for s in summary.schemas.values()} >= {"geometry_msgs/msg/PoseArray", "rosgraph_msgs/msg/Clock"}
    for schema in summary.schemas.values():
        assert schema.data.decode() == message_definition(schema.name), schema.name
    assert sum(summary.statistics.channel_message_counts.values()) > 0

    report = tmp_path / "report"
    done = run(noros, tmp_path, "mta", "analyze", str(bag), "-o", str(report))
    assert done.returncode == 0, done.stderr
    assert (report / "summary.json").is_file() and list(report.glob("*.png")), sorted(report.iterdir())

    done = run(noros, tmp_path, "mta", "replay", str(bag), "--resimulate")
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1] == "identical", done.stdout

    done = run(noros, REPO, "python", "-m", "benchmarks", "tick-parts", "--scene", SCENE, "--rounds", "1", "--calls", "1")
    assert done.returncode == 0, done.stderr
    assert "markers (MarkerArray)" in done.stdout, done.stdout

    # mta sweep's libraries are setup.py's extra 'sweep', not in a plain install: one line says so
    done = run(noros, tmp_path, "mta", "sweep", "sweeps/hitching.yaml")
    assert done.returncode == 1, done.stderr
    assert done.stderr.splitlines() == [
        "mta sweep: needs dask[distributed], pyarrow, pandas, SALib, not installed here: pip install "
        "'mta_sim_ros[sweep]' (or 'dask[distributed]' 'pyarrow' 'pandas' 'SALib')"], done.stderr
