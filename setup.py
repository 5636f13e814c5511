"""Build script for the ament_python package mta_sim_ros.

Works both for colcon (ament_python build type, `ros2 run mta_sim_ros <exe>`)
and for plain pip (`pip install -e .` puts `mta` on the venv's bin/):

* colcon runs `setup.py install --install-scripts $base/lib/mta_sim_ros`
  (taken from setup.cfg [install] install_scripts), so the console scripts
  land in <install>/mta_sim_ros/lib/mta_sim_ros where `ros2 run` looks.
* pip builds a wheel; a wheel carries entry points rather than scripts, and
  pip generates the launchers in the environment's scripts dir (bin/), so
  setup.cfg's install_scripts does not apply there.
* after colcon's install, the kernels are compiled into numba's cache beside
  the installed sources (InstallAndCompile), so that the first node start
  ticks within ~1 s instead of compiling for ~13 s; `make venv` runs
  `mta compile` for the venv.
"""

import glob
import os
import subprocess
import sys
from collections import defaultdict

from setuptools import find_packages, setup
from setuptools.command.install import install

package_name = 'mta_sim_ros'


#: What goes to share/<pkg>/, as globs relative to setup.py: the scene, train and parameter YAML
#: files, the Fast DDS loopback profile, the RViz config and the Foxglove layout, and the launch
#: files (``ros2 launch mta_sim_ros sim.launch.py`` looks in share/<pkg>/launch).
SHARE_GLOBS = (
    'config/**/*.yaml',
    'config/*.xml',
    'config/**/*.rviz',
    'config/**/*.json',
    'config/**/*.geojson',
    'config/**/*.csv',  # height grids (config/terrain/)
    'launch/*.launch.py',
)


def share_data_files():
    """Install every file SHARE_GLOBS match to share/<pkg>/<its folder>, keeping subfolders.

    Globbed at build time so new scene/train files are picked up without
    editing this file. Paths stay relative to setup.py (setuptools and colcon
    require relative data_files sources).
    """
    here = os.path.dirname(os.path.abspath(__file__))
    by_dir = defaultdict(list)
    found = set()
    for pattern in SHARE_GLOBS:
        found.update(glob.glob(os.path.join(here, pattern), recursive=True))
    for path in sorted(found):
        rel = os.path.relpath(path, here)
        by_dir[os.path.join('share', package_name, os.path.dirname(rel))].append(rel)
    return sorted(by_dir.items())


class InstallAndCompile(install):
    """`setup.py install` as colcon runs it, then `mta compile` on what it installed.

    Only for an install in place (no --root: a wheel's staging install would compile for paths
    that do not last); MTA_SIM_NO_COMPILE=1 skips it. A failure is said and the install stands:
    the first start then compiles, as before."""

    def run(self):
        super().run()
        if self.root is not None or os.environ.get('MTA_SIM_NO_COMPILE') == '1':
            return
        env = dict(os.environ)
        env['PYTHONPATH'] = os.pathsep.join(p for p in (self.install_lib, env.get('PYTHONPATH', '')) if p)
        # config_dir() finds the installed share/ through the ament index of this prefix
        env['AMENT_PREFIX_PATH'] = os.pathsep.join(p for p in (self.prefix, env.get('AMENT_PREFIX_PATH', '')) if p)
        try:
            done = subprocess.run([sys.executable, '-m', 'mta_sim_ros.cli', 'compile', '--quiet'], env=env,
                                  cwd=self.install_lib, capture_output=True, text=True, timeout=1800)
            said = (done.stdout + done.stderr).strip().splitlines() or ['(nothing said)']
            print(said[-1] if done.returncode == 0 else
                  f'mta_sim_ros: compiling the kernels failed (exit {done.returncode}: {said[-1]}); the first '
                  f'start compiles them instead, or run `ros2 run mta_sim_ros mta compile`')
        except (OSError, subprocess.SubprocessError) as err:
            print(f'mta_sim_ros: compiling the kernels failed ({err}); the first start compiles them instead')


setup(
    name=package_name,
    cmdclass={'install': InstallAndCompile},
    version='0.1.0',
    # benchmarks/ (top level) measure a checkout; they are not installed
    packages=find_packages(exclude=['test', 'test.*', 'benchmarks', 'benchmarks.*']),
    data_files=[
        ('share/ament_index/resource_index/packages',
            ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ] + share_data_files(),
    # The vendored ROS message definitions (bag/msg/README.md): bags written without a ROS install.
    package_data={package_name + '.bag': ['msg/*/*.msg', 'msg/*/LICENSE', 'msg/LICENSE', 'msg/README.md', 'msg/type_hashes.json']},
    # Plain-Python runtime deps only: `pip install .` alone runs mta run, check, analyze, replay
    # --resimulate and the benchmarks that need no DDS (test/test_no_ros.py does so in a venv
    # without ROS). The ROS 2 wheels (ros-jazzy-rclpy, ros-jazzy-common-interfaces) are
    # deliberately NOT listed: on a real ROS install rclpy and the message packages come from the
    # ROS distro (apt), and pip must not pull a second, conflicting copy. See requirements.txt.
    # Lower bounds: Ubuntu 24.04's versions (the python3-* packages of a ROS Jazzy install), which
    # `make test-noble` tests (constraints-noble.txt); `make test` tests current PyPI's.
    install_requires=[
        'numpy>=1.26.4',
        'scipy>=1.11.4',
        'pyyaml>=6.0',
        'mcap>=1.5',  # BagWriter.flush() needs mcap's Writer.flush(), new in 1.5
        'mcap-ros2-support>=0.5',
        # mcap's chunk codecs (mcap requires them): mta recover unpacks chunks with them directly,
        # never past what a chunk claims
        'zstandard>=0.21',
        'lz4>=4.0.2',
        # The figures are what `mta analyze` (and so `mta session`, `make run`) is for, and
        # package.xml makes python3-matplotlib a hard dependency of a ROS install too.
        'matplotlib>=3.6.3',
        # mta field: the field's geometry (shapely: GEOS) and its projection (pyproj: PROJ)
        'shapely>=2.0.3',
        'pyproj>=3.6.1',
        # `mta linearize`: exact derivatives of the chain's equations on symbols (linear.py); pure Python
        'sympy>=1.12',
    ],
    # numba (the compiled kernels, physics/kernel/) is an extra, not a hard requirement: the
    # package runs without it (same results on the Python path, slower), numba's LLVM wheels are
    # large and lag new Python releases, and a failed numba install must not block installing
    # the simulator. requirements.txt (the venvs, CI) and package.xml (rosdep) do pull it in.
    # Tested with 0.59.1 (make test-noble) and 0.68.1 (make test).
    extras_require={
        'jit': ['numba>=0.59.1'],
        'test': ['pytest>=7', 'hypothesis>=6.100', 'yourdfpy>=0.0.56'],
        # `mta sweep` (mta_sim_ros/sweep/): the Dask engine, Parquet results, the report's tables
        # and Saltelli/Sobol. An extra: the simulator, the node and `mta run` need none of them.
        'sweep': ['dask[distributed]>=2024.1', 'pyarrow>=14', 'pandas>=2.1.4', 'SALib>=1.5.1'],
        # a scene's height grid from a GeoTIFF (physics/geotiff.py); .csv and .npy grids need nothing
        'terrain': ['rasterio>=1.3.9'],
    },
    zip_safe=True,
    maintainer='mta_sim_ros maintainers',
    maintainer_email='mta-sim-ros@example.com',
    description='Tractor-train (multi-trailer) simulator for ROS 2 Jazzy',
    license='Apache-2.0',
    python_requires='>=3.10',
    entry_points={
        'console_scripts': [
            'mta = mta_sim_ros.cli:main',
            'sim_node = mta_sim_ros.node.sim_node:main',
        ],
    },
)
