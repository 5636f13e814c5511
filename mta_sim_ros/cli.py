"""``mta``: the package's one command-line entry, with subcommands.

Exit codes: 0 done; 2 an input refused (a file, an argument, a parameter, a bag's metadata), said
in one line ``mta COMMAND: FIELD: VALUE ... must be RULE`` (validate.py); 1 the work failed for
another reason (a file that cannot be written, a bag that cannot be read); 3 ``mta run`` stopped
by a validity guard; 130 interrupted (Ctrl-C).
"""
from __future__ import annotations

import argparse
import importlib
import math
import sys

from .validate import EXIT_INPUT, InputError, one_line

EXIT_INTERRUPTED = 130  # as a shell reports a process ended by SIGINT


class Parser(argparse.ArgumentParser):
    """argparse with its faults in one line (no usage block): ``mta run: argument --rate: ...``,
    exit code 2. Subcommands' parsers are of this class too (argparse makes them so)."""

    def error(self, message: str):
        self.exit(EXIT_INPUT, f"{self.prog}: {one_line(message)}\n")


def check_main(args: argparse.Namespace) -> int:
    """The files by their readers' rules (``checked_file``), and what a run builds from a train or
    scene beyond those: the robot model (its frames and joints named after the carts), so check
    refuses what run, urdf and the node would; a note where a scene's set speed is one its governor
    cannot hold on the level, or up a plane's fall line whatever the scene's path (the level
    chooser's bound, run.fidelity.unheld_speed; none on a height grid): a run's report says whether it did."""
    from .config import resolve_config_path
    from .messages.urdf import robot_model
    from .physics.loader import check_files
    from .physics.spec import Scene, Train
    from .run.fidelity import unheld_speed

    def built(loaded) -> list[str]:
        if not isinstance(loaded, (Scene, Train)):
            return []
        robot_model(loaded.train if isinstance(loaded, Scene) else loaded)
        if not isinstance(loaded, Scene):
            return []
        unheld = unheld_speed(loaded)
        notes = [f"speed: {unheld} (whether it does on the scene's path, a run's report says: set speed held)"] \
            if unheld else []
        ticks = loaded.duration * loaded.publish_rate
        if abs(ticks - round(ticks)) > 1e-9:  # a run takes the whole ticks within the duration
            whole = math.floor(ticks + 1e-9)
            notes.append(f"duration: {loaded.duration:g} s is not a whole number of ticks at {loaded.publish_rate:g} "
                         f"Hz: a run takes {whole} ticks, {whole / loaded.publish_rate:.6g} s")
        return notes

    return check_files([resolve_config_path(f) for f in args.files], built, checked_file)


def checked_file(path):
    """A file ``mta check`` takes, read by its own reader: a field (GeoJSON, or YAML with
    ``boundary``), a field scene (``field``: field.scene.is_field_scene), a sweep (``vary``), else a
    train (``carts``) or a scene (``train``)."""
    from pathlib import Path

    from .physics.loader import load_file, read_yaml_mapping

    if Path(path).suffix.lower() in (".geojson", ".json"):
        from .field.boundary import load_field

        return load_field(path)
    data = read_yaml_mapping(path)
    if "vary" in data:
        from .sweep.spec import load

        return load(path)
    if "boundary" in data:
        from .field.boundary import load_field

        return load_field(path)
    from .field.scene import is_field_scene, load_field_scene

    if is_field_scene(data):  # as mta field run and a sweep tell them
        return load_field_scene(path)
    return load_file(path)


def urdf_main(args: argparse.Namespace) -> int:
    """Print the URDF of a scene's train as the node in ``--namespace`` publishes it on
    robot_description (urdf.py), e.g. for robot_state_publisher's robot_description parameter."""
    from .config import resolve_config_path
    from .messages.urdf import NAMESPACE, frame_prefix, robot_model
    from .physics.loader import load_scene
    from .validate import fail, show

    if not NAMESPACE.test(args.namespace):
        fail("--namespace", show(args.namespace), NAMESPACE.text)
    scene = load_scene(resolve_config_path(args.scene))
    sys.stdout.write(robot_model(scene.train, frame_prefix(args.namespace)).urdf)
    return 0


def recover_main(args: argparse.Namespace) -> int:
    """Exit 2 when the paths are refused (bag.output_target: nothing read or written), 1 when the
    bag cannot be rebuilt, 0 when it is; one line on stderr either way it fails."""
    from pathlib import Path

    from .bag import BagError, PathRefused, recover

    out = args.output or str(Path(args.bag).with_suffix(".recovered.mcap"))
    try:
        report = recover(args.bag, str(out))
    except PathRefused as err:
        print(f"mta recover: {err}", file=sys.stderr)
        return 2
    except (BagError, OSError) as err:
        print(f"mta recover: {err}", file=sys.stderr)
        return 1
    print(f"{out}: {report['total_messages']} messages in {report['chunks']} chunks recovered; "
          f"dropped {report['chunks_dropped']} chunks, {report['messages_dropped']} messages"
          + (f" ({report['messages_out_of_order']} whose log time went back)" if report['messages_out_of_order'] else "")
          + f", {report['bytes_dropped']} bytes")
    return 0


def node_main(args: argparse.Namespace) -> int:
    from .config import resolve_config_path
    from .node.sim_node import main

    params = resolve_config_path(args.params_file or "sim.yaml")
    return main(["mta_node", "--ros-args", "--params-file", params, *args.ros_args[1:]])


def add_tool(sub, name: str, help: str, selected: str | None = None) -> None:
    """A subcommand implemented by ``mta_sim_ros.tools.<name>`` (its docstring is the description).

    The module is imported only when it is the ``selected`` command: the ROS tools import rclpy,
    and ``mta run``, ``check`` or ``analyze`` must work where ROS is not installed."""
    if name != selected:
        sub.add_parser(name, help=help)
        return
    module = importlib.import_module(f".tools.{name}", __package__)
    p = sub.add_parser(name, help=help, description=module.__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    module.add_arguments(p)
    p.set_defaults(func=module.main)


def selected_command(argv: list[str]) -> str | None:
    """The subcommand named in ``argv`` (its first argument that is not an option), if any."""
    return next((a for a in argv if not a.startswith("-")), None)


def build_parser(selected: str | None = None) -> argparse.ArgumentParser:
    """The ``mta`` parser; the tool ``selected`` gets its own arguments (see add_tool)."""

    parser = Parser(prog="mta", description="Multi-element machine-tractor unit simulator (ROS 2).")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    add_tool(sub, "run", "simulate a scene offline, as fast as possible, into an MCAP bag", selected)

    p = sub.add_parser("node", help="the ROS 2 simulator node (as `ros2 run mta_sim_ros sim_node`)",
                       description="Runs the simulator node until SIGINT/SIGTERM. Parameters: config/sim.yaml.")
    p.add_argument("--params-file", help="ROS parameters YAML (default: config/sim.yaml)")
    p.epilog = "Further ROS arguments follow --ros-args, e.g. mta node --ros-args -r __ns:=/unit1"
    p.set_defaults(func=node_main)

    add_tool(sub, "maneuver", "a node playing a scene's steering (or a named manoeuvre) on sim time", selected)

    add_tool(sub, "follow", "an example controller node: pure pursuit along a field path", selected)

    add_tool(sub, "reverse", "an example controller node: backing the train up a straight line (LQR)", selected)

    add_tool(sub, "rsp_feed", "a node setting the simulator's robot_description on robot_state_publisher", selected)

    p = sub.add_parser("recover", help="rebuild a readable bag from one cut short (SIGKILL, power loss)")
    p.add_argument("bag", help="the damaged .mcap")
    p.add_argument("-o", "--output", help="where to write (default: <bag>.recovered.mcap)")
    p.set_defaults(func=recover_main)

    add_tool(sub, "replay", "play a bag back over ROS 2 with its timing, or re-simulate it (--resimulate)", selected)

    add_tool(sub, "analyze", "plots, summary and CSV of one bag, or of several compared", selected)

    p = sub.add_parser("check", help="validate train, scene, field and sweep files without running them")
    p.add_argument("files", nargs="+", help="trains, scenes, fields (YAML or GeoJSON), field scenes, sweeps "
                                            "(config/{trains,scenes,fields,fieldwork,sweeps}/*)")
    p.set_defaults(func=check_main)

    p = sub.add_parser("urdf", help="print the URDF of a scene's train, as the node publishes it on robot_description")
    p.add_argument("--scene", default="scenes/headland_turn.yaml",
                   help="scene YAML whose train it is (default: the node's, scenes/headland_turn.yaml)")
    p.add_argument("--namespace", default="/", help="the node's namespace: its frames' prefix (/unit1 -> unit1/)")
    p.set_defaults(func=urdf_main)

    add_tool(sub, "session", "the main job: node + manoeuvre headless, then the bag's analysis", selected)

    add_tool(sub, "equations", "the scheme's equations of motion as the article states them (sympy)", selected)

    add_tool(sub, "linearize", "the train's linear model about straight motion or a steady turn: A, B, eigenvalues",
             selected)

    add_tool(sub, "sweep", "synthesis: many hitching schemes run and compared (Dask), report and export", selected)

    add_tool(sub, "field", "field operations: plan a field for a train, work it offline, report it", selected)

    add_tool(sub, "compile", "compile the kernels into numba's cache once, after an install (first start ~1 s)",
             selected)

    return parser


def ros_missing(err: ModuleNotFoundError) -> bool:
    """Whether ``err`` is a ROS 2 package this install lacks (rclpy, a message package, ...)."""
    top = (err.name or "").split(".")[0]
    return top in ("rclpy", "rcl_interfaces", "builtin_interfaces", "rosidl_runtime_py", "rosbag2_py") or \
        top.endswith(("_msgs", "_srvs", "_interfaces"))


def missing_ros(command: str | None, err: ModuleNotFoundError) -> int:
    """One line for a ROS command run where ROS 2 (or one of its message packages) is missing."""
    print(f"mta {command or ''}: needs ROS 2 Jazzy's {err.name} ({err}): source /opt/ros/jazzy/setup.bash, "
          "or make venv (README: the ROS packages as wheels, tf2_msgs, ackermann_msgs and simulation_interfaces "
          "built into it); "
          "mta run, check, analyze, equations, linearize, sweep and field need no ROS", file=sys.stderr)
    return 1


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    # everything from --ros-args on belongs to ROS (as for any ROS executable)
    split = argv.index("--ros-args") if "--ros-args" in argv else len(argv)
    selected = selected_command(argv[:split])
    try:
        parser = build_parser(selected)  # a ROS tool imports rclpy here
    except ModuleNotFoundError as err:
        if not ros_missing(err):
            raise
        return missing_ros(selected, err)
    args = parser.parse_args(argv[:split])
    args.ros_args = argv[split:]
    try:
        return args.func(args)
    except InputError as err:  # the commands say their own; this is the net under them
        print(f"mta {args.command}: {err}", file=sys.stderr)
        return EXIT_INPUT
    except ModuleNotFoundError as err:  # the node's own imports (mta node), a message package missing
        if not ros_missing(err):
            raise
        return missing_ros(args.command, err)
    except KeyboardInterrupt:  # Ctrl-C: what was written is closed or removed by the command's own finally
        print(f"mta {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
