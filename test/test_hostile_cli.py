"""Hostile command lines: every number, choice and output path of `mta run` and of every other
tool. Each bad argument is one case: exit code 2, one line naming the option, the value and the
rule, no traceback; nothing is written, and a bag already at the path is not lost, also when the
run fails after its bag was opened."""
from __future__ import annotations

from pathlib import Path

import pytest

from hostile import CONFIG, assert_refused, mta, recorded_run, short_scene

pytestmark = pytest.mark.slow  # a process of its own for every case

OLD_BAG = b"an earlier run's bag"


@pytest.fixture
def place(tmp_path):
    """A scene, a file and a folder in the way, and an earlier bag that must survive."""
    (tmp_path / "FILE").write_text("a file")
    (tmp_path / "DIR").mkdir()
    (tmp_path / "old.mcap").write_bytes(OLD_BAG)
    return tmp_path


def written(folder: Path) -> set[str]:
    """Every file under ``folder`` but the fixture's own."""
    return {str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file()} - {
        "FILE", "old.mcap", "short.yaml", "long.yaml"}


#: (id, arguments after `mta run --scene S --quiet`, texts the one line must hold)
RUN_FAULTS = [
    ("rate-nan", ["--rate", "nan"], ["argument --rate: nan", "a finite number in [1, 1000] Hz"]),
    ("rate-inf", ["--rate", "inf"], ["argument --rate: inf", "a finite number"]),
    ("rate-negative", ["--rate", "-1"], ["argument --rate: -1", "in [1, 1000] Hz"]),
    ("rate-tiny", ["--rate", "1e-300"], ["argument --rate: 1e-300", "in [1, 1000] Hz"]),
    ("rate-zero", ["--rate", "0"], ["argument --rate: 0", "in [1, 1000] Hz"]),
    ("rate-text", ["--rate", "fast"], ["argument --rate: fast", "a number"]),
    ("step-negative", ["--step", "-1"], ["argument --step: -1", "> 0"]),
    ("step-nan", ["--step", "nan"], ["argument --step: nan", "a finite number > 0"]),
    ("step-zero", ["--step", "0"], ["argument --step: 0", "> 0"]),
    ("step-tiny", ["--step", "1e-9"], ["--step: 1e-09", "[2e-06, 0.02] s"]),
    ("step-past-tick", ["--step", "0.5"], ["--step: 0.5", "1/publish_rate]"]),
    ("method", ["--method", "rk5"], ["argument --method: invalid choice: 'rk5'", "RK45"]),
    ("fidelity", ["--fidelity", "magic"], ["argument --fidelity: invalid choice: 'magic'"]),
    ("bag-under-a-file", ["--bag", "{tmp}/FILE/x.mcap"], ["--bag: ", "FILE is a file"]),
    ("bag-is-a-folder", ["--bag", "{tmp}/DIR"], ["--bag: ", "a file path: it is a folder"]),
    ("report-is-a-folder", ["--report", "{tmp}/DIR"], ["--report: ", "it is a folder"]),
    ("report-cannot-be-made", ["--report", "{tmp}/" + "x" * 300 + ".md"], ["--report: ", "(File name too long)"]),
    ("report-under-proc", ["--report", "/proc/mta/report.md"], ["--report: '/proc/mta/report.md'", "cannot be written"]),
    ("report-is-the-bag", ["--bag", "{tmp}/old.mcap", "--report", "{tmp}/old.mcap"], ["--report: ", "another file than the bag"]),
    ("bag-is-the-scene", ["--bag", "{tmp}/short.yaml"], ["--bag: ", "another file than the input"]),
    ("rate-past-the-ticks", ["--rate", "1000", "--scene", "{tmp}/long.yaml"], ["--rate: 1000", "at most 1e+07 ticks"]),
    ("steps-past-the-run", ["--step", "2e-6", "--scene", "{tmp}/long.yaml"], ["--step: 2e-06", "at most 1e+08 integrator steps"]),
]


@pytest.mark.parametrize("case,args,expected", RUN_FAULTS, ids=[c[0] for c in RUN_FAULTS])
def test_a_bad_run_argument_is_one_line_and_nothing_is_written(place, case, args, expected):
    short_scene(place)
    short_scene(place, duration=12000.0, name="long")
    args = [a.replace("{tmp}", str(place)) for a in args]
    scene = [] if "--scene" in args else ["--scene", place / "short.yaml"]
    bag = [] if "--bag" in args else ["--bag", place / "old.mcap"]
    assert_refused(mta("run", *scene, *bag, "--quiet", *args, cwd=place), *expected)
    assert (place / "old.mcap").read_bytes() == OLD_BAG
    assert written(place) == set()


def test_a_run_failing_after_its_bag_opened_loses_no_earlier_bag(place):
    """A train whose governor is too fast for rk4 at any step within the bound: the simulation
    refuses it once the bag is open; the earlier bag stays, no part of the new one is left."""
    train = place / "twitchy.yaml"
    train.write_text((CONFIG / "trains" / "default.yaml").read_text()
                     .replace("mass: 16000", "mass: 1e-6").replace("mass: 10000", "mass: 1e-6")
                     .replace("mass: 8000", "mass: 1e-6").replace("kp: 34000", "kp: 1e9"))
    scene = short_scene(place, train=train)
    line = assert_refused(mta("run", "--scene", scene, "--bag", place / "old.mcap", "--quiet",
                              "--fidelity", "dynamic", cwd=place), "integrator step: ", "steps per 0.02 s tick")
    assert "speed governor" in line
    assert (place / "old.mcap").read_bytes() == OLD_BAG
    assert written(place) == {"twitchy.yaml"}


def test_a_good_run_replaces_the_earlier_bag_whole(place):
    done = mta("run", "--scene", short_scene(place), "--bag", place / "old.mcap", "--quiet", cwd=place)
    assert done.returncode == 0, done.stderr
    assert (place / "old.mcap").read_bytes()[:8] == b"\x89MCAP0\r\n"
    assert written(place) == {"old.md"}


#: (id, command line, texts the one line must hold)
TOOL_FAULTS = [
    ("replay-rate-zero", ["replay", "{bag}", "--rate", "0"], ["argument --rate: 0", "in [0.001, 1000]"]),
    ("replay-rate-nan", ["replay", "{bag}", "--rate", "nan"], ["argument --rate: nan", "a finite number"]),
    ("replay-start-negative", ["replay", "{bag}", "--start", "-1"], ["argument --start: -1", ">= 0"]),
    ("replay-wait-inf", ["replay", "{bag}", "--wait-for-subscribers", "inf"], ["--wait-for-subscribers: inf"]),
    ("resimulate-method", ["replay", "{bag}", "--resimulate", "--method", "rk5"], ["argument --method: invalid choice"]),
    ("resimulate-step-nan", ["replay", "{bag}", "--resimulate", "--step", "nan"], ["argument --step: nan"]),
    ("analyze-into-a-file", ["analyze", "{bag}", "-o", "{tmp}/FILE"], ["--output: ", "a folder: it is a file"]),
    ("analyze-under-a-file", ["analyze", "{bag}", "-o", "{tmp}/FILE/report"], ["--output: ", "FILE is a file"]),
    ("recover-onto-itself", ["recover", "{bag}", "-o", "{bag}"], ["(the same file): refusing to write over"]),
    ("recover-into-a-folder", ["recover", "{bag}", "-o", "{tmp}/DIR"], ["DIR is a directory"]),
    ("follow-passes", ["follow", "--passes", "0"], ["argument --passes: 0", "in [1, 100]"]),
    ("follow-length", ["follow", "--length", "1e300"], ["argument --length: 1e300", "(0, 5000] m"]),
    ("follow-report", ["follow", "--report", "{tmp}/DIR"], ["argument --report: ", "it is a folder"]),
    ("maneuver-name", ["maneuver", "--maneuver", "uturn"], ["argument --maneuver: invalid choice: 'uturn'"]),
    ("maneuver-duration", ["maneuver", "--duration", "nan"], ["argument --duration: nan", "a finite number"]),
    ("maneuver-param-alone", ["maneuver", "--param", "t0=1"], ["--param: given without --maneuver"]),
    ("maneuver-param-nan", ["maneuver", "--maneuver", "step", "--param", "t0=nan"], ["t0: nan", "a finite number"]),
    ("rsp-feed-target", ["rsp_feed", "--target", "robot state"], ["argument --target: 'robot state'", "a node name"]),
    ("rsp-feed-target-slash", ["rsp_feed", "--target", "rsp/"], ["argument --target: 'rsp/'", "a node name"]),
    ("session-rate", ["session", "--rate", "0"], ["argument --rate: 0", "in [1, 1000]"]),
    ("session-rtf", ["session", "--real-time-factor", "-1"], ["argument --real-time-factor: -1", "in [0, 1000]"]),
    ("session-bag-dir", ["session", "--bag-dir", "{tmp}/FILE"], ["argument --bag-dir: ", "it is a file"]),
    ("session-scene", ["session", "--scene", "{tmp}/FILE"], ["file: a str", "a YAML mapping"]),
    ("bench-rate", ["bench", "realtime", "--rate", "nan"], ["argument --rate: nan"]),
    ("bench-duration", ["bench", "realtime", "--duration", "1e300"], ["argument --duration: 1e300", "(0, 1e+06] s"]),
    ("bench-domain", ["bench", "realtime", "--domain-id", "999"], ["argument --domain-id: 999", "in [0, 232]"]),
    ("bench-repeats", ["bench", "method", "--repeats", "0"], ["argument --repeats: 0", "in [1, 1e+06]"]),
    ("bench-out", ["bench", "kinks", "--out", "{tmp}/DIR"], ["argument --out: ", "it is a folder"]),
    ("bench-ticks", ["bench", "scaling", "--ticks", "many"], ["argument --ticks: many", "an integer"]),
    ("bench-sigkill-factor", ["bench", "sigkill", "--factors", "1", "nan"], ["argument --factors: nan", "in [0, 1000]"]),
    ("bench-lanes-values", ["bench", "lanes", "--values", "0"], ["argument --values: 0", "in [64, 1e+07]"]),
    ("node-params-file-folder", ["node", "--params-file", "{tmp}/DIR"], ["file: unreadable"]),
    ("no-command", ["fly"], ["argument COMMAND: invalid choice: 'fly'"]),
    ("equations-onto-its-train", ["equations", "{tmp}/train.yaml", "--out", "{tmp}/train.yaml"],
     ["--out: ", "another file than the input", "train.yaml"]),
    ("equations-onto-a-link-to-it", ["equations", "{tmp}/train.yaml", "--out", "{tmp}/link.yaml"],
     ["--out: ", "link.yaml", "another file than the input"]),
    ("equations-onto-the-scenes-train", ["equations", "{tmp}/short.yaml", "--out", "{tmp}/train.yaml"],
     ["--out: ", "another file than the input"]),
    ("linearize-into-a-folder", ["linearize", "{tmp}/train.yaml", "--out", "{tmp}/DIR/"],
     ["--out: ", "a file name prefix", "not a folder"]),
    ("linearize-a-folder", ["linearize", "{tmp}/train.yaml", "--out", "{tmp}/DIR"], ["--out: ", "not a folder"]),
    ("linearize-empty", ["linearize", "{tmp}/train.yaml", "--out", ""], ["--out: ''", "a file name prefix"]),
    ("linearize-onto-its-train", ["linearize", "{tmp}/t.md", "--out", "{tmp}/t"], ["--out: ", "t.md", "the input"]),
    ("rsp-feed-target-long", ["rsp_feed", "--target", "a" * 300], ["argument --target: 'aaa", "at most 160 characters"]),
    ("reverse-override-not-yaml", ["reverse", "--ros-args", "-p", "x:=[unclosed"],
     ["--ros-args -p 'x:=[unclosed'", "one YAML value"]),
    ("follow-override-not-yaml", ["follow", "--ros-args", "-p", "x:={a: 1"], ["--ros-args -p 'x:={a: 1'", "one YAML value"]),
    ("node-override-not-yaml", ["node", "--ros-args", "-p", "x:=[unclosed"], ["--ros-args -p 'x:=[unclosed'", "one YAML value"]),
    ("reverse-override-no-value", ["reverse", "--ros-args", "-p", "novalue"], ["--ros-args -p 'novalue'", "NAME:=VALUE"]),
    # a remapped node name or namespace rcl refuses only when it makes the node
    *((f"{command}-node-name-too-long", [command, "--ros-args", "-r", "__node:=" + "n" * 300],
       ["--ros-args", "node name length should not exceed"])
      for command in ("node", "follow", "reverse", "maneuver", "rsp_feed")),
    ("reverse-namespace-too-long", ["reverse", "--ros-args", "-r", "__ns:=/" + "n" * 300],
     ["--ros-args -r __ns:=/nnn", "invalid node namespace"]),
    ("reverse-settle-past-the-distance", ["reverse", "--distance", "10", "--settle", "50"],
     ["--settle: 50", "less than --distance 10 m"]),
    ("follow-settle-past-a-pass", ["follow", "--length", "30", "--settle", "40"], ["--settle: 40", "less than a pass"]),
    ("follow-default-settle-past-a-pass", ["follow", "--length", "5"], ["--settle: ", "twice the train's length"]),
    ("sweep-workers-past-the-cpus", ["sweep", str(CONFIG / "sweeps" / "hitching.yaml"), "--workers", "100000"],
     ["--workers: 100000", "at most", "CPUs this process may use"]),
    ("sweep-out-empty", ["sweep", str(CONFIG / "sweeps" / "hitching.yaml"), "--out", ""], ["--out: ''", "not empty"]),
    ("sweep-scheduler-empty", ["sweep", str(CONFIG / "sweeps" / "hitching.yaml"), "--scheduler", ""],
     ["--scheduler: ''", "not empty"]),
]


@pytest.fixture(scope="module")
def bag(tmp_path_factory) -> Path:
    """The bag the tools' cases read (and must leave as it is)."""
    return recorded_run(tmp_path_factory.mktemp("hostile_cli"))


@pytest.mark.parametrize("case,args,expected", TOOL_FAULTS, ids=[c[0] for c in TOOL_FAULTS])
def test_a_bad_argument_of_any_tool_is_one_line_and_exit_2(place, bag, case, args, expected):
    before = bag.read_bytes()
    inputs = trains_in(place)  # a train file (and a link to it, and one named t.md) a tool reads
    args = [a.replace("{tmp}", str(place)).replace("{bag}", str(bag)) for a in args]
    assert_refused(mta(*args, cwd=place, timeout=60), *expected)
    assert bag.read_bytes() == before
    assert written(place) == set(inputs)
    assert all((place / name).read_bytes() == text for name, text in inputs.items())  # none written over


def trains_in(place: Path) -> dict[str, bytes]:
    """The default train copied into ``place`` as train.yaml and t.md, link.yaml a link to train.yaml,
    and short.yaml a scene naming train.yaml: {name: bytes} of the files (the link counted once)."""
    text = (CONFIG / "trains" / "default.yaml").read_bytes()
    (place / "train.yaml").write_bytes(text)
    (place / "t.md").write_bytes(text)
    (place / "link.yaml").symlink_to(place / "train.yaml")
    scene = (CONFIG / "scenes" / "straight_pass.yaml").read_text().replace("../trains/default.yaml", "train.yaml")
    (place / "short.yaml").write_text(scene)
    return {"train.yaml": text, "t.md": text, "link.yaml": text}


def test_a_write_error_of_equations_is_one_line_and_no_device_is_replaced(place):
    """/dev/full takes the write and fails it (ENOSPC): one line, exit 1, and /dev/full is still the
    device (a partial file renamed onto it would have replaced it for root)."""
    trains_in(place)
    done = mta("equations", str(place / "train.yaml"), "--out", "/dev/full", cwd=place, timeout=60)
    assert_refused(done, "--out /dev/full cannot be written", "No space left on device", code=1)
    assert Path("/dev/full").is_char_device()


WITHOUT_ROS = [("rclpy", [c]) for c in ("node", "reverse", "follow", "rsp_feed", "session", "maneuver")] + [
    ("tf2_msgs", ["node"]), ("tf2_msgs", ["session"])]  # the node's /tf: a message package built into the venv


@pytest.mark.parametrize("missing,command", WITHOUT_ROS, ids=[f"{m}-{c[0]}" for m, c in WITHOUT_ROS])
def test_a_ros_command_without_ros_says_so_in_one_line(tmp_path, missing, command):
    """An install without ROS 2 (or without a message package built into it): a package of that
    name first on the path that cannot be imported stands in for its absence. One line naming it
    and what to do, exit 1, nothing started."""
    import os
    import subprocess
    import sys

    from dds import ros_env

    shadow = tmp_path / missing
    shadow.mkdir()
    (shadow / "__init__.py").write_text(f"raise ModuleNotFoundError(\"No module named '{missing}'\", name='{missing}')\n")
    env = ros_env()
    env["PYTHONPATH"] = os.pathsep.join((str(tmp_path), env["PYTHONPATH"]))
    done = subprocess.run([sys.executable, "-m", "mta_sim_ros.cli", *command], capture_output=True, text=True,
                          cwd=tmp_path, timeout=60, env=env)
    line = assert_refused(done, f"needs ROS 2 Jazzy's {missing}", "make venv", code=1)
    assert line.startswith(f"mta {command[0]}: ")
