"""Packaging checks for the ament_python package mta_sim_ros.

(a) package.xml is a valid format-3 ament_python manifest and declares every
    ROS package (and every rosdep-backed Python library) that the code under
    mta_sim_ros/ imports, so a forgotten <exec_depend> fails here rather than
    on a real ROS install.
(b) `colcon build` of a copy of the package produces the layout `ros2 run`
    relies on: executables in lib/mta_sim_ros/, package.xml and the config
    YAML files in share/mta_sim_ros/, and the ament index marker; and the one
    `ros2 launch` relies on: the launch files, the RViz config and the Foxglove
    layout in share/mta_sim_ros/, with every executable and file the launch
    files name present in the install (test_launch.py checks the rest).
"""

import ast
import os
import re
import shutil
import stat
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PKG = 'mta_sim_ros'

# Top-level modules that are ROS packages even though their names do not end
# in _msgs/_srvs/_interfaces.
_ROS_MODULES = {
    'rclpy', 'ament_index_python', 'rosidl_runtime_py', 'launch',
    'launch_ros', 'tf2_ros', 'rosbag2_py', 'message_filters',
}
_ROS_SUFFIXES = ('_msgs', '_srvs', '_interfaces')

# Third-party (non-ROS) modules: import name -> rosdep key in package.xml.
_ROSDEP_KEYS = {
    'numpy': 'python3-numpy',
    'scipy': 'python3-scipy',
    'yaml': 'python3-yaml',
    'matplotlib': 'python3-matplotlib',
    'numba': 'python3-numba',  # physics/kernel/ (optional at run time; also in requirements.txt)
    # jit.py's LLVM option: numba's own binding, which numba requires (no rosdistro key of its own:
    # python3-numba brings it, as pip's numba does; docs/dependencies.md)
    'llvmlite': 'python3-numba',
    # mta field: the field's geometry and its projection (rosdistro's keys)
    'shapely': 'python3-shapely',
    'pyproj': 'python3-pyproj',
    'sympy': 'python3-sympy',
    'pandas': 'python3-pandas',
    'psutil': 'python3-psutil',
    'mcap_ros2': 'mcap-ros2-support',
    'rasterio': 'python3-rasterio',  # a GeoTIFF height grid (also setup.py's extra `terrain`)
}
#: the plain (non-ROS-package) rosdep keys rosdistro defines that package.xml may name, read from
#: rosdep/python.yaml of ros/rosdistro at 8468e88 (2026-08-22): a key not in rosdistro makes
#: `rosdep install` fail for every user who has not added a source of their own
ROSDISTRO_KEYS = {
    'python3-numpy', 'python3-scipy', 'python3-yaml', 'python3-matplotlib', 'python3-shapely', 'python3-pyproj',
    'python3-numba', 'mcap-ros2-support', 'python3-sympy', 'python3-pandas', 'python3-psutil', 'python3-pytest',
    'python3-hypothesis', 'python3-rasterio',
}
#: the ROS packages package.xml may name: released for Jazzy, read from jazzy/distribution.yaml of
#: ros/rosdistro at 8468e88 (each repository's release packages); rosdep resolves only those
ROSDISTRO_JAZZY_PACKAGES = {
    'rclpy', 'rcl_interfaces', 'builtin_interfaces', 'ament_index_python', 'std_msgs', 'geometry_msgs',
    'sensor_msgs', 'rosgraph_msgs', 'visualization_msgs', 'diagnostic_msgs', 'std_srvs', 'nav_msgs', 'tf2_msgs',
    'ackermann_msgs', 'simulation_interfaces', 'launch', 'launch_ros', 'ros2launch',
    'ament_copyright', 'ament_flake8', 'ament_pep257',
}
# Third-party modules without a rosdep key: import name -> PyPI distribution
# that must be listed in requirements.txt (mcap comes with mcap-ros2-support's key).
_PIP_ONLY = {
    'mcap': 'mcap',
    'mcap_ros2': 'mcap-ros2-support',
    'rosbags': 'rosbags',
    'zstandard': 'zstandard',  # mcap's chunk codecs (mcap requires them), used by mta recover
    'lz4': 'lz4',
}
#: mta sweep's engine libraries, without a rosdistro key: setup.py's extra 'sweep'
_SWEEP_EXTRA = {'dask': 'dask', 'distributed': 'dask', 'pyarrow': 'pyarrow', 'SALib': 'SALib', 'pandas': 'pandas'}
#: a GeoTIFF height grid's reader, without a rosdistro key checked: setup.py's extra 'terrain'
_TERRAIN_EXTRA = {'rasterio': 'rasterio'}


def _manifest():
    return ET.parse(REPO / 'package.xml').getroot()


def _imported_top_level_modules(paths=None):
    """Map top-level module name -> list of 'file:line' that import it (in ``paths``, default
    every module of the package)."""
    found = {}
    for path in sorted((REPO / PKG).rglob('*.py')) if paths is None else paths:
        tree = ast.parse(path.read_text(encoding='utf-8'), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split('.')[0]
                where = f'{path.relative_to(REPO)}:{node.lineno}'
                found.setdefault(top, []).append(where)
    return found


def _is_ros_module(name):
    return name in _ROS_MODULES or name.endswith(_ROS_SUFFIXES)


def _requirement_names():
    names = set()
    for line in (REPO / 'requirements.txt').read_text().splitlines():
        line = line.split('#', 1)[0].strip()
        if line:
            names.add(re.split(r'[\[<>=!~;\s]', line, maxsplit=1)[0].lower())
    return names


def test_manifest_format_and_build_type():
    root = _manifest()
    assert root.tag == 'package'
    assert root.get('format') == '3'
    assert root.findtext('name') == PKG
    assert root.findtext('license') == 'Apache-2.0'
    assert root.find('maintainer') is not None
    assert (root.findtext('description') or '').strip()
    assert root.findtext('export/build_type') == 'ament_python'


def test_versions_agree():
    xml_version = _manifest().findtext('version')
    setup_version = re.search(r"version\s*=\s*['\"]([^'\"]+)['\"]",
                              (REPO / 'setup.py').read_text()).group(1)
    init_version = re.search(r"__version__\s*=\s*['\"]([^'\"]+)['\"]",
                             (REPO / PKG / '__init__.py').read_text()).group(1)
    assert xml_version == setup_version == init_version


def test_setup_cfg_puts_scripts_where_ros2_run_looks():
    import configparser
    cfg = configparser.ConfigParser()
    cfg.read(REPO / 'setup.cfg')
    assert cfg.get('develop', 'script_dir') == f'$base/lib/{PKG}'
    assert cfg.get('install', 'install_scripts') == f'$base/lib/{PKG}'


def test_every_imported_ros_package_is_an_exec_depend():
    root = _manifest()
    exec_deps = {e.text.strip() for e in root.findall('exec_depend')}
    exec_deps |= {e.text.strip() for e in root.findall('depend')}
    imports = _imported_top_level_modules()

    missing = {name: where for name, where in imports.items()
               if _is_ros_module(name) and name not in exec_deps}
    assert not missing, (
        'ROS packages imported but not declared as <exec_depend> in '
        f'package.xml: {missing}')

    missing_keys = {f'{name} -> {_ROSDEP_KEYS[name]}': where
                    for name, where in imports.items()
                    if name in _ROSDEP_KEYS and _ROSDEP_KEYS[name] not in exec_deps}
    assert not missing_keys, (
        f'Python libraries imported without their rosdep key in package.xml: {missing_keys}')

    reqs = _requirement_names()
    missing_pip = {f'{name} -> {_PIP_ONLY[name]}': where
                   for name, where in imports.items()
                   if name in _PIP_ONLY and _PIP_ONLY[name] not in reqs}
    assert not missing_pip, (
        f'Python libraries imported but missing from requirements.txt: {missing_pip}')


def test_every_plain_rosdep_key_is_rosdistros():
    """`rosdep install --from-paths src --ignore-src -y` with rosdep's default sources: every key
    of package.xml that is not a ROS package is one rosdistro defines (no -pip key of our own)."""
    root = _manifest()
    keys = {e.text.strip() for tag in ('exec_depend', 'depend', 'test_depend', 'build_depend')
            for e in root.findall(tag)}
    plain = {k for k in keys if k.startswith('python3-') or k in ROSDISTRO_KEYS or k.endswith('-pip')}
    assert plain and plain <= ROSDISTRO_KEYS, plain - ROSDISTRO_KEYS
    assert keys - plain <= ROSDISTRO_JAZZY_PACKAGES, keys - plain - ROSDISTRO_JAZZY_PACKAGES


def test_the_sweep_libraries_are_the_sweep_extra():
    """What mta sweep imports without a rosdistro key is setup.py's extra 'sweep' (and
    requirements.txt, which the venvs install), and what mta sweep names when it is missing."""
    from mta_sim_ros.tools.sweep import LIBRARIES

    setup = (REPO / 'setup.py').read_text()
    extra = ast.literal_eval(re.search(r"'sweep': (\[.*\])", setup).group(1))
    named = {re.split(r'[\[<>=]', part)[0] for part in extra}
    imports = _imported_top_level_modules(sorted((REPO / PKG / 'sweep').rglob('*.py')))
    for module, dist in _SWEEP_EXTRA.items():
        if module in imports:
            assert dist in named, (module, dist, named)
            assert dist.lower() in {r.lower() for r in _requirement_names()}, dist
    assert set(LIBRARIES.values()) <= named | {'dask[distributed]'}, LIBRARIES


def test_the_launch_files_imports_are_exec_depends():
    """launch/*.launch.py run on the user's ROS install: every ROS package they import is an
    <exec_depend>, and they import nothing else but the standard library and this package."""
    root = _manifest()
    exec_deps = {e.text.strip() for e in root.findall('exec_depend')}
    imports = _imported_top_level_modules(sorted((REPO / 'launch').glob('*.launch.py')))
    assert {'launch', 'launch_ros'} <= set(imports)
    missing = {name: where for name, where in imports.items() if _is_ros_module(name) and name not in exec_deps}
    assert not missing, f'ROS packages the launch files import, not <exec_depend>: {missing}'
    other = {name: where for name, where in imports.items()
             if not _is_ros_module(name) and name not in sys.stdlib_module_names and name != PKG}
    assert not other, f'the launch files import undeclared modules: {other}'
    assert 'ros2launch' in exec_deps, '`ros2 launch` itself'


def test_no_unknown_third_party_imports():
    """A new third-party import must be declared; then add it to the maps above."""
    own = {PKG, 'test'}
    known = set(_ROSDEP_KEYS) | set(_PIP_ONLY) | set(_SWEEP_EXTRA) | set(_TERRAIN_EXTRA) | own
    unknown = {name: where for name, where in _imported_top_level_modules().items()
               if name not in sys.stdlib_module_names and name not in known
               and not _is_ros_module(name)}
    assert not unknown, (
        'Imports of undeclared third-party modules (declare them in package.xml '
        'or requirements.txt/setup.py, then add them to _ROSDEP_KEYS, _SWEEP_EXTRA or '
        f'_PIP_ONLY in test/test_package.py): {unknown}')


# --------------------------------------------------------------------------
# colcon build
# --------------------------------------------------------------------------

_COPY_ITEMS = ('package.xml', 'setup.py', 'setup.cfg', 'resource', PKG, 'config', 'launch')

_PLACEHOLDER_MAIN = '''"""Test-only placeholder (the real module does not exist yet)."""
import sys


def main(argv=None):
    print('placeholder', __name__, sys.argv[1:])
    return 0
'''


def _colcon_executable():
    venv_colcon = Path(sys.executable).parent / 'colcon'
    if venv_colcon.exists():
        return str(venv_colcon)
    on_path = shutil.which('colcon')
    if on_path:
        return on_path
    if os.environ.get('CI'):
        pytest.fail('colcon not found (it is in requirements.txt: run `make venv`)')
    pytest.skip('colcon not installed in this interpreter\'s environment')


def _build_env(tmp_path):
    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.setdefault('ROS_DOMAIN_ID', '42')
    # Keep colcon away from the user's ~/.colcon defaults (e.g. a
    # --symlink-install default) and from any sourced workspace.
    env['COLCON_HOME'] = str(tmp_path / 'colcon_home')
    for var in ('COLCON_DEFAULTS_FILE', 'COLCON_PREFIX_PATH'):
        env.pop(var, None)
    env['PYTHONDONTWRITEBYTECODE'] = '1'
    # the install's own cache beside its sources (make test-noble points numba elsewhere)
    env.pop('NUMBA_CACHE_DIR', None)
    return env


@pytest.fixture(scope='module')
def colcon_install(tmp_path_factory):
    """Build a copy of the package with colcon; return (src, install, proc)."""
    tmp_path = tmp_path_factory.mktemp('colcon')
    colcon = _colcon_executable()
    src = tmp_path / 'src' / PKG
    src.mkdir(parents=True)
    ignore = shutil.ignore_patterns('__pycache__', '*.pyc', '*.egg-info')
    for item in _COPY_ITEMS:
        source = REPO / item
        if source.is_dir():
            shutil.copytree(source, src / item, ignore=ignore)
        elif source.exists():
            shutil.copy2(source, src / item)
    # Entry-point modules may not exist yet: placeholders in the copy only.
    for module in ('cli', 'node'):
        target = src / PKG / f'{module}.py'
        if not target.exists():
            target.write_text(_PLACEHOLDER_MAIN)
    # A nested YAML proves the config glob keeps subfolders and picks up new files.
    extra = src / 'config' / 'scenes' / 'zz_colcon_probe' / 'probe.yaml'
    extra.parent.mkdir(parents=True, exist_ok=True)
    extra.write_text('probe: true\n')

    cmd = [
        colcon, '--log-base', str(tmp_path / 'log'),
        'build',
        '--base-paths', str(tmp_path / 'src'),
        '--build-base', str(tmp_path / 'build'),
        '--install-base', str(tmp_path / 'install'),
        '--event-handlers', 'console_direct-', 'console_cohesion+',
    ]
    proc = subprocess.run(cmd, cwd=tmp_path, env=_build_env(tmp_path),
                          stdin=subprocess.DEVNULL, capture_output=True,
                          text=True, timeout=900)
    return src, tmp_path / 'install' / PKG, proc


def _output(proc):
    return f'\n--- stdout ---\n{proc.stdout[-6000:]}\n--- stderr ---\n{proc.stderr[-6000:]}'


@pytest.mark.slow
def test_colcon_build_succeeds(colcon_install):
    _, install, proc = colcon_install
    assert proc.returncode == 0, f'colcon build failed{_output(proc)}'
    assert install.is_dir(), _output(proc)


@pytest.mark.slow
def test_colcon_installs_executables_for_ros2_run(colcon_install):
    _, install, proc = colcon_install
    assert proc.returncode == 0, _output(proc)
    for exe in ('mta', 'sim_node'):
        path = install / 'lib' / PKG / exe
        assert path.is_file(), f'{path} missing; lib/{PKG}: ' + str(
            sorted(p.name for p in (install / 'lib' / PKG).glob('*'))
            if (install / 'lib' / PKG).is_dir() else 'absent')
        assert path.stat().st_mode & stat.S_IXUSR, f'{path} is not executable'
    assert not (install / 'bin' / 'mta').exists(), 'scripts must not go to bin/'


@pytest.mark.slow
def test_colcon_build_compiles_the_kernels_into_the_install(colcon_install):
    """setup.py's InstallAndCompile: numba's cache (an index .nbi and the code .nbc of each
    compiled function) lies beside the installed kernel sources, made by `mta compile` run on
    the install, so that a first start of the installed node compiles nothing."""
    _, install, proc = colcon_install
    assert proc.returncode == 0, _output(proc)
    assert 'mta compile: the kernels are in numba' in proc.stdout + proc.stderr, _output(proc)
    [package] = install.glob(f'lib/python3*/site-packages/{PKG}')
    cached = {p.parent.parent.relative_to(package).as_posix() + '/' + p.name.split('.')[0]
              for p in package.rglob('__pycache__/*.nbi')}
    assert {'physics/kernel/entries', 'integrate/rk', 'run/whole'} <= cached, sorted(cached)
    assert all(list(package.rglob(f'__pycache__/{Path(c).name}.*.nbc')) for c in cached)


@pytest.mark.slow
def test_colcon_installs_share_files(colcon_install):
    src, install, proc = colcon_install
    assert proc.returncode == 0, _output(proc)
    share = install / 'share' / PKG
    assert (share / 'package.xml').is_file()
    assert (install / 'share' / 'ament_index' / 'resource_index' / 'packages' / PKG).is_file()
    yamls = sorted(p.relative_to(src) for p in (src / 'config').rglob('*.yaml'))
    assert yamls, 'no config YAML in the copy'
    for rel in yamls:
        assert (share / rel).is_file(), f'{rel} not installed to {share / rel}'


@pytest.mark.slow
def test_colcon_installs_the_launch_files_and_the_views(colcon_install):
    """launch/*.launch.py to share/<pkg>/launch (where `ros2 launch mta_sim_ros X` looks), and
    every file of config/ (the RViz config, the Foxglove layout, the loopback profile too)."""
    src, install, proc = colcon_install
    assert proc.returncode == 0, _output(proc)
    share = install / 'share' / PKG
    wanted = sorted(p.relative_to(src) for p in (src / 'launch').glob('*.launch.py'))
    wanted += sorted(p.relative_to(src) for p in (src / 'config').rglob('*') if p.is_file())
    assert any(p.suffix == '.rviz' for p in wanted) and any(p.suffix == '.json' for p in wanted)
    missing = [str(rel) for rel in wanted if not (share / rel).is_file()]
    assert not missing, f'not installed to {share}: {missing}'


@pytest.mark.slow
def test_launch_files_name_only_what_the_install_has(colcon_install):
    """Each mta_sim_ros executable a launch file starts is in the install's lib/mta_sim_ros, and
    each file it joins under share/mta_sim_ros (params file, RViz config, included launch files)
    is in the install's share/mta_sim_ros: read from the installed launch files themselves."""
    import launchfiles

    _, install, proc = colcon_install
    assert proc.returncode == 0, _output(proc)
    share, lib = install / 'share' / PKG, install / 'lib' / PKG
    installed = sorted((share / 'launch').glob('*.launch.py'))
    assert installed
    for path in installed:
        lf = launchfiles.read(path)
        assert lf.problems == [], lf.problems
        for node in lf.nodes:
            if node.package == PKG:
                exe = lib / node.executable
                assert exe.is_file() and exe.stat().st_mode & stat.S_IXUSR, f'{node.where}: {exe} missing'
        for joined in lf.share_paths + [i.path for i in lf.includes]:
            assert joined.package == PKG and None not in joined.parts, joined
            assert (share / Path(*joined.parts)).is_file(), f'{joined.where}: {joined.parts} not in {share}'


@pytest.mark.slow
def test_colcon_installs_every_module(colcon_install):
    """Every .py under mta_sim_ros/ is installed (a subpackage without
    __init__.py would silently be left out by find_packages)."""
    src, install, proc = colcon_install
    assert proc.returncode == 0, _output(proc)
    site = list(install.glob(f'lib/python3*/site-packages/{PKG}'))
    assert len(site) == 1, f'installed package not found under {install}/lib'
    missing = [str(p.relative_to(src)) for p in sorted((src / PKG).rglob('*.py'))
               if not (site[0].parent / p.relative_to(src)).is_file()]
    assert not missing, (
        f'not installed by colcon (missing __init__.py in a subpackage?): {missing}')


@pytest.mark.slow
def test_colcon_installs_the_vendored_message_definitions(colcon_install):
    """bag/msg (the .msg files a bag is written with where no ROS share dir has them, their
    LICENSE and README) is package data: installed beside the modules."""
    src, install, proc = colcon_install
    assert proc.returncode == 0, _output(proc)
    site = next(install.glob(f'lib/python3*/site-packages/{PKG}'))
    files = sorted(p.relative_to(src / PKG) for p in (src / PKG / 'bag' / 'msg').rglob('*') if p.is_file())
    assert len(files) > 3, files
    missing = [str(rel) for rel in files if not (site / rel).is_file()]
    assert not missing, f'not installed by colcon (setup.py package_data): {missing}'


@pytest.mark.slow
def test_installed_mta_script_runs(colcon_install, tmp_path):
    """The generated launcher imports mta_sim_ros from the install space."""
    _, install, proc = colcon_install
    assert proc.returncode == 0, _output(proc)
    site = next(install.glob('lib/python3*/site-packages'))
    env = _build_env(tmp_path)
    env['PYTHONPATH'] = os.pathsep.join(
        [str(site)] + ([env['PYTHONPATH']] if env.get('PYTHONPATH') else []))
    run = subprocess.run([str(install / 'lib' / PKG / 'mta'), '--help'],
                         cwd=tmp_path, env=env, stdin=subprocess.DEVNULL,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, _output(run)


def test_every_relative_link_of_the_docs_resolves_in_the_repository():
    """The README stands alone: each [text](target) of README.md and docs/**/*.md that is not a
    URL names a file or folder of this repository (the part before any #anchor)."""
    import re

    broken = []
    for doc in [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]:
        for target in re.findall(r"\]\(([^)\s]+)\)", doc.read_text()):
            if re.match(r"[a-z]+:", target) or target.startswith("#"):
                continue
            path = (doc.parent / target.split("#", 1)[0]).resolve()
            if not path.exists() or REPO.resolve() not in (path, *path.parents):
                broken.append(f"{doc.relative_to(REPO)}: {target}")
    assert not broken, broken


def test_the_terrain_extra_declares_what_a_geotiff_grid_imports():
    """rasterio is imported only by physics/geotiff.py, lazily, and declared as setup.py's extra
    'terrain' and in requirements.txt (what the venvs install)."""
    setup = (REPO / 'setup.py').read_text(encoding='utf-8')
    extra = ast.literal_eval(re.search(r"'terrain': (\[.*\])", setup).group(1))
    reqs = (REPO / 'requirements.txt').read_text(encoding='utf-8')
    for module, dist in _TERRAIN_EXTRA.items():
        assert any(e.startswith(dist) for e in extra)
        assert re.search(rf'^{dist}\b', reqs, re.M)
        where = _imported_top_level_modules().get(module, [])
        assert where and all(w.startswith(f'{PKG}/physics/geotiff.py:') for w in where), where
