"""The launch files, the RViz config and the Foxglove layout name only what exists.

launch and launch_ros have no wheels here, so the launch files are read, not run
(``launchfiles.py``): they must compile and define generate_launch_description; each Node must be
an executable of this package (console scripts, installed by colcon: test_package.py checks the
install) or of a documented optional tool; each parameter must be one the receiving node
declares (``params.PARAMS`` for sim_node; the tools' own lists below, from their sources); each
``mta`` subcommand and option must be the CLI's; each launch argument read must be declared and
each declared one read; each include must pass only arguments the included file declares.

The RViz config and the Foxglove layout use only keys of their formats (RViz2 Jazzy's display
properties; Foxglove's panel configs), listed below with the source files they come from, and
name only topics and frames that a running node has: the last tests start the node over real
DDS and compare with its graph, its QoS and the frames of its messages (its URDF read by
ElementTree, not by our own code). ``mta rsp_feed``, the node that feeds robot_state_publisher,
is tested over DDS against a stand-in with robot_state_publisher's parameter and refusal.
"""
from __future__ import annotations

import ast
import json
import py_compile
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import launchfiles
import pytest
import rclpy
import yaml
from dds import REPO, ros_env, start_node, stop, write_params
from geometry_msgs.msg import PoseArray
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
from std_msgs.msg import String

from mta_sim_ros import cli
from mta_sim_ros.node import params
from mta_sim_ros.tools.rsp_feed import DESCRIPTION_QOS

PKG = "mta_sim_ros"
RVIZ_CONFIG = REPO / "config" / "rviz" / "mta.rviz"
FOXGLOVE_LAYOUT = REPO / "config" / "foxglove" / "mta_layout.json"
NODE = "mta_sim"  # params.NODE_NAME: the node the views look at, in the root namespace

#: Optional tools a launch file may start: not exec_depend of package.xml (the simulator runs
#: without them; rviz2 alone pulls Qt and OGRE onto a headless machine), installed by the user
#: (README). Their executables and the parameters they declare, from their ROS 2 Jazzy sources:
#: robot_state_publisher src/robot_state_publisher.cpp (3.3.3), foxglove_bridge
#: ros2_foxglove_bridge/launch/foxglove_bridge_launch.xml, rviz2 (no node parameters of its own).
#: use_sim_time is every node's (rclcpp declares it).
OPTIONAL_TOOLS = {
    "robot_state_publisher": ({"robot_state_publisher"},
                              {"robot_description", "publish_frequency", "ignore_timestamp", "frame_prefix",
                               "use_sim_time"}),
    "rviz2": ({"rviz2"}, {"use_sim_time"}),
    "foxglove_bridge": ({"foxglove_bridge"},
                        {"port", "address", "tls", "certfile", "keyfile", "topic_whitelist", "param_whitelist",
                         "service_whitelist", "client_topic_whitelist", "min_qos_depth", "max_qos_depth",
                         "num_threads", "send_buffer_limit", "use_sim_time", "capabilities", "include_hidden",
                         "asset_uri_allowlist", "ignore_unresponsive_param_nodes"}),
}
#: rviz2's command-line options (rviz_common/src/rviz_common/visualizer_app.cpp, Jazzy)
RVIZ2_OPTIONS = {"-d", "--display-config", "-f", "--fixed-frame", "-t", "--display-title-format", "-l",
                 "--ogre-log", "-s", "--splash-screen", "--fullscreen"}


def console_scripts() -> set[str]:
    """The executables setup.py installs to lib/mta_sim_ros (its console_scripts)."""
    tree = ast.parse((REPO / "setup.py").read_text())
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Dict):
            for key, value in zip(node.keys, node.values):
                if launchfiles.text(key) == "console_scripts":
                    found |= {launchfiles.text(e).split("=")[0].strip() for e in value.elts}
    return found


def node_parameters(package: str, executable: str) -> set[str]:
    """The parameters the node started as package/executable declares."""
    if package == PKG:
        return {p.name for p in params.PARAMS} if executable == "sim_node" else set()  # mta: none of its own
    return OPTIONAL_TOOLS[package][1]


@pytest.fixture(scope="module")
def launch_files():
    return launchfiles.read_all()


# --------------------------------------------------------------------------- the launch files


def test_every_launch_file_compiles_and_defines_generate_launch_description(launch_files):
    assert {"sim.launch.py", "rviz.launch.py", "foxglove.launch.py"} <= set(launch_files)
    for name, lf in launch_files.items():
        py_compile.compile(str(lf.path), doraise=True, cfile=None, optimize=-1)
        defs = [n for n in lf.tree.body if isinstance(n, ast.FunctionDef) and n.name == "generate_launch_description"]
        assert len(defs) == 1, f"{name}: no top-level generate_launch_description()"
        required = len(defs[0].args.args) - len(defs[0].args.defaults)
        assert required == 0, f"{name}: generate_launch_description() must take no arguments"
        assert lf.problems == [], lf.problems


def test_launch_arguments_read_are_declared_and_declared_ones_read(launch_files):
    for name, lf in launch_files.items():
        assert lf.read - set(lf.declared) == set(), f"{name} reads undeclared launch arguments"
        assert set(lf.declared) - lf.read == set(), f"{name} declares launch arguments it never reads"
        for arg, call in lf.declared.items():
            assert launchfiles.text(launchfiles.keyword(call, "description")), f"{name}: {arg} has no description"


def test_nodes_are_this_packages_executables_or_documented_tools(launch_files):
    scripts = console_scripts()
    assert {"sim_node", "mta"} <= scripts
    depends = {e.text.strip() for e in ET.parse(REPO / "package.xml").getroot().findall("exec_depend")}
    started = set()
    for lf in launch_files.values():
        for node in lf.nodes:
            started.add(node.package)
            if node.package == PKG:
                assert node.executable in scripts, f"{node.where}: {node.executable} is no executable of {PKG}"
            else:
                assert node.package in OPTIONAL_TOOLS, f"{node.where}: {node.package} is no documented tool"
                assert node.executable in OPTIONAL_TOOLS[node.package][0], f"{node.where}: {node.executable}"
                assert node.package not in depends, f"{node.package} is optional: not an exec_depend"
    assert started == {PKG, *OPTIONAL_TOOLS}, started


def test_parameters_are_declared_by_the_node_they_go_to(launch_files):
    for lf in launch_files.values():
        for node in lf.nodes:
            unknown = node.parameters - node_parameters(node.package, node.executable)
            assert not unknown, f"{node.where}: {node.package}/{node.executable} declares no parameter {unknown}"
    sim = [n for n in launch_files["sim.launch.py"].nodes if n.executable == "sim_node"]
    # the name the tf work gives the node's switch for the cart frames (issue 12): it must match
    assert len(sim) == 1 and "publish_cart_frames" in sim[0].parameters


def test_mta_commands_and_options_are_the_clis(launch_files):
    for name, lf in launch_files.items():
        allowed = set()
        for node in lf.nodes:
            if node.executable == "mta":
                assert node.arguments, f"{node.where}: mta without a command"
                command = node.arguments[0]
                parser = cli.build_parser(command)
                sub = next(a for a in parser._actions if a.dest == "command")  # argparse's subparsers
                assert command in sub.choices, f"{node.where}: mta has no command {command!r}"
                allowed |= {o for a in sub.choices[command]._actions for o in a.option_strings}
            elif node.executable == "rviz2":
                allowed |= RVIZ2_OPTIONS
        assert lf.options <= allowed, f"{name}: options no program it starts takes: {lf.options - allowed}"


def test_includes_pass_only_arguments_the_included_file_declares(launch_files):
    includes = [i for lf in launch_files.values() for i in lf.includes]
    assert includes
    for inc in includes:
        assert inc.path.package == PKG and inc.path.parts[0] == "launch", inc
        included = launch_files[inc.path.parts[-1]]
        assert inc.arguments <= set(included.declared), f"{inc.where}: {inc.arguments - set(included.declared)}"


def test_share_paths_name_files_of_the_checkout(launch_files):
    """Each file a launch file joins under share/mta_sim_ros is a file setup.py installs there from
    this checkout (the installed tree: test_package.py)."""
    for lf in launch_files.values():
        paths = lf.share_paths + [i.path for i in lf.includes]
        for path in paths:
            assert path.package == PKG and None not in path.parts, path
            assert (REPO / Path(*path.parts)).is_file(), f"{path.where}: {'/'.join(path.parts)} is no file"


# --------------------------------------------------------------------------- the RViz config

#: RViz2 Jazzy's display classes used here and the properties each one has (rviz_default_plugins
#: src/rviz_default_plugins/displays/*/..._display.cpp, robot/robot.cpp for Links, rviz_common
#: message_filter_display.hpp for Filter size), plus every display's own Class, Name, Enabled, Value
RVIZ_DISPLAY = {"Class", "Name", "Enabled", "Value"}
RVIZ_PROPERTIES = {
    "rviz_default_plugins/Grid": {"Reference Frame", "Plane Cell Count", "Normal Cell Count", "Cell Size",
                                  "Line Style", "Color", "Alpha", "Plane", "Offset"},
    "rviz_default_plugins/TF": {"Show Names", "Show Axes", "Show Arrows", "Marker Scale", "Update Interval",
                                "Frame Timeout", "Filter (whitelist)", "Filter (blacklist)", "Frames", "Tree"},
    "rviz_default_plugins/RobotModel": {"Visual Enabled", "Collision Enabled", "Mass Properties", "Update Interval",
                                        "Alpha", "Description Source", "Description File", "Description Topic",
                                        "TF Prefix", "Links"},
    "rviz_default_plugins/MarkerArray": {"Topic", "Namespaces"},
    "rviz_default_plugins/PoseArray": {"Topic", "Filter size", "Shape", "Color", "Alpha", "Arrow Length",
                                       "Head Radius", "Head Length", "Shaft Radius", "Shaft Length", "Axes Length",
                                       "Axes Radius"},
    "rviz_default_plugins/Odometry": {"Topic", "Filter size", "Position Tolerance", "Angle Tolerance", "Keep",
                                      "Shape", "Covariance"},
    "rviz_default_plugins/Map": {"Topic", "Update Topic", "Alpha", "Color Scheme", "Draw Behind", "Resolution",
                                 "Width", "Height", "Position", "Orientation", "Use Timestamp"},
    "rviz_default_plugins/Path": {"Topic", "Filter size", "Line Style", "Line Width", "Color", "Alpha",
                                  "Buffer Length", "Offset", "Pose Style", "Pose Color", "Pose Alpha"},
}
#: the topics of the field follower (mta follow --plan/--field: controllers/implement/field_node.py),
#: not the simulator's: latched (reliable, transient local) as it publishes them
FIELD_TOPICS = {"plan", "field_boundary", "coverage"}
#: a topic property's fields (rviz_common ros_topic_display.hpp, properties/qos_profile_property.cpp)
RVIZ_TOPIC = {"Value": None, "Depth": None, "History Policy": {"System Default", "Keep Last", "Keep All"},
              "Reliability Policy": {"System Default", "Reliable", "Best Effort"},
              "Durability Policy": {"System Default", "Transient Local", "Volatile"}}
RVIZ_TOPIC_PROPERTIES = {"Topic", "Description Topic"}


def rviz_config() -> dict:
    return yaml.safe_load(RVIZ_CONFIG.read_text())


def rviz_topics(config: dict) -> dict[str, dict]:
    """Display name -> its topic property (relative name in Value, QoS)."""
    found = {}
    for display in config["Visualization Manager"]["Displays"]:
        for prop in RVIZ_TOPIC_PROPERTIES & set(display):
            found[display["Name"]] = display[prop]
    return found


def rviz_frames(config: dict) -> set[str]:
    manager = config["Visualization Manager"]
    return {manager["Global Options"]["Fixed Frame"], manager["Views"]["Current"]["Target Frame"]}


def test_rviz_config_is_rviz2_yaml_with_the_displays_of_the_train():
    config = rviz_config()
    manager = config["Visualization Manager"]
    assert manager["Global Options"]["Fixed Frame"] == "odom"
    displays = manager["Displays"]
    assert {d["Class"] for d in displays} == set(RVIZ_PROPERTIES)
    for d in displays:
        unknown = set(d) - RVIZ_DISPLAY - RVIZ_PROPERTIES[d["Class"]]
        assert not unknown, f"{d['Name']}: no property {unknown} in {d['Class']}"
    topics = rviz_topics(config)
    assert {t["Value"] for t in topics.values()} == {"robot_description", "markers", "hitch_poses", "odom",
                                                     *FIELD_TOPICS}
    for topic in topics.values():
        if topic["Value"] in FIELD_TOPICS:
            assert (topic["Durability Policy"], topic["Reliability Policy"]) == ("Transient Local", "Reliable")
    for name, topic in topics.items():
        assert set(topic) <= set(RVIZ_TOPIC), f"{name}: {set(topic) - set(RVIZ_TOPIC)}"
        for field, choices in RVIZ_TOPIC.items():
            assert choices is None or topic.get(field, "System Default") in choices, f"{name}: {field}"
        assert not topic["Value"].startswith("/"), f"{name}: relative, so that RViz in a namespace shows its node"
    model = next(d for d in displays if d["Class"] == "rviz_default_plugins/RobotModel")
    assert model["Description Source"] == "Topic"


# --------------------------------------------------------------------------- the Foxglove layout

#: Foxglove's layout and panel configs (foxglove/studio v1, packages/studio-base/src/panels):
#: ThreeDeeRender/IRenderer.ts RendererConfig, camera.ts CameraState, renderables/Grids.ts
#: LayerSettingsGrid, Plot/types.ts PlotConfig (+ the keys of dataSources/SampleNuscenesLayout.json),
#: Plot/internalTypes.ts PlotPath, diagnostics/util.ts DiagnosticSummaryConfig,
#: RawMessages/types.ts RawMessagesPanelConfig
FOXGLOVE_LAYOUT_KEYS = {"configById", "globalVariables", "userNodes", "linkedGlobalVariables", "playbackConfig",
                        "layout"}
FOXGLOVE_PANELS = {
    "3D": {"cameraState", "followTf", "followMode", "scene", "publish", "transforms", "topics", "layers",
           "imageMode"},
    "Plot": {"title", "paths", "minYValue", "maxYValue", "showLegend", "isSynced", "showTooltips", "xAxisVal",
             "xAxisPath", "followingViewWidth", "legendDisplay", "showPlotValuesInLegend", "showXAxisLabels",
             "showYAxisLabels", "sidebarDimension"},
    "DiagnosticSummary": {"minLevel", "pinnedIds", "topicToRender", "hardwareIdFilter", "sortByLevel"},
    "RawMessages": {"diffEnabled", "diffMethod", "diffTopicPath", "showFullMessageForDiff", "topicPath"},
}
FOXGLOVE_CAMERA = {"distance", "perspective", "phi", "target", "targetOffset", "targetOrientation", "thetaOffset",
                   "fovy", "near", "far"}
FOXGLOVE_GRID = {"visible", "frameLocked", "label", "instanceId", "layerId", "order", "frameId", "size", "divisions",
                 "lineWidth", "color", "position", "rotation"}
FOXGLOVE_PLOT_PATH = {"value", "enabled", "color", "label", "timestampMethod", "showLine"}
FOXGLOVE_SPLIT = {"first", "second", "direction", "splitPercentage"}


def foxglove_layout() -> dict:
    return json.loads(FOXGLOVE_LAYOUT.read_text())


def foxglove_panels_in(tree) -> list[str]:
    """The panel ids a layout tree (splits of first/second) places."""
    if isinstance(tree, str):
        return [tree]
    assert set(tree) <= FOXGLOVE_SPLIT and tree["direction"] in ("row", "column"), tree
    return foxglove_panels_in(tree["first"]) + foxglove_panels_in(tree["second"])


def foxglove_topics(layout: dict) -> dict[str, str]:
    """Topic -> the panel that shows it (a message path's topic is what precedes its first '.')."""
    found = {}
    for pid, cfg in layout["configById"].items():
        kind = pid.split("!")[0]
        names = {"3D": lambda: list(cfg["topics"]),
                 "Plot": lambda: [p["value"].split(".")[0] for p in cfg["paths"]],
                 "DiagnosticSummary": lambda: [cfg["topicToRender"]],
                 "RawMessages": lambda: [cfg["topicPath"].split(".")[0]]}[kind]()
        found.update((name, pid) for name in names)
    return found


def foxglove_frames(layout: dict) -> set[str]:
    frames = set()
    for pid, cfg in layout["configById"].items():
        if pid.startswith("3D!"):
            frames.add(cfg["followTf"])
            frames |= {layer["frameId"] for layer in cfg["layers"].values() if "frameId" in layer}
    return frames


def test_foxglove_layout_has_the_panels_of_the_brief_in_foxgloves_schema():
    layout = foxglove_layout()
    assert set(layout) <= FOXGLOVE_LAYOUT_KEYS
    panels = layout["configById"]
    assert sorted(foxglove_panels_in(layout["layout"])) == sorted(panels), "every panel placed once"
    for pid, cfg in panels.items():
        kind = pid.split("!")[0]
        assert kind in FOXGLOVE_PANELS, pid
        assert set(cfg) <= FOXGLOVE_PANELS[kind], f"{pid}: {set(cfg) - FOXGLOVE_PANELS[kind]}"
        if kind == "3D":
            assert set(cfg["cameraState"]) <= FOXGLOVE_CAMERA
            assert cfg["followMode"] in ("follow-pose", "follow-position", "follow-none")
            for layer in cfg["layers"].values():
                assert layer["layerId"] == "foxglove.Grid" and set(layer) <= FOXGLOVE_GRID, layer
            assert {"/tf", "/markers", "/hitch_poses"} <= set(cfg["topics"]) and cfg["followTf"] == "base_link"
        if kind == "Plot":
            assert cfg["xAxisVal"] == "timestamp"
            for path in cfg["paths"]:
                assert set(path) <= FOXGLOVE_PLOT_PATH and path["timestampMethod"] in ("receiveTime", "headerStamp")
    topics = foxglove_topics(layout)
    plotted = {t for t, pid in topics.items() if pid.startswith("Plot!")}
    assert {"/traction_power", "/applied_steering"} <= plotted
    assert topics["/diagnostics"].startswith("DiagnosticSummary!")
    assert topics["/joint_states"].startswith("RawMessages!")


# --------------------------------------------------------------------------- against a running node


def urdf_links(text: str) -> set[str]:
    return {link.get("name") for link in ET.fromstring(text).iter("link")}


@pytest.mark.dds
def test_views_name_the_running_nodes_topics_qos_and_frames(tmp_path, probe):
    """Start the node as sim.launch.py does in the root namespace (config/sim.yaml's values),
    read its graph (publishers and subscriptions) and the frames of its odometry, poses and URDF,
    and check every topic and frame the RViz config and the Foxglove layout name against them."""
    node = start_node(write_params(tmp_path / "p.yaml", record=False), tmp_path / "node.log")
    try:
        description = probe.subscribe("robot_description", String, DESCRIPTION_QOS)
        odometry = probe.subscribe("odom", Odometry)
        poses = probe.subscribe("hitch_poses", PoseArray)
        config, layout = rviz_config(), foxglove_layout()
        wanted = {"/" + t["Value"] for t in rviz_topics(config).values()} | set(foxglove_topics(layout))
        wanted -= {"/" + t for t in FIELD_TOPICS}  # the field follower's (test_follow_field.py hears them)

        def graph() -> set[str]:
            """The node's topics (published and subscribed); none while discovery has not found it."""
            try:
                names = probe.node.get_publisher_names_and_types_by_node(NODE, "/")
                names += probe.node.get_subscriber_names_and_types_by_node(NODE, "/")
            except rclpy.node.NodeNameNonExistentError:
                return set()
            return {name for name, _ in names}

        def seen() -> bool:
            return bool(description and odometry and poses) and wanted <= graph()

        probe.spin_until(seen, 90.0)
        assert node.poll() is None, (tmp_path / "node.log").read_text()[-3000:]
        assert wanted - graph() == set(), "topics the views name that the node has not"
        assert description and odometry and poses, "no robot_description, odom or hitch_poses from the node"

        for name, topic in rviz_topics(config).items():
            if topic["Value"] in FIELD_TOPICS:
                continue
            mine = [i for i in probe.node.get_publishers_info_by_topic("/" + topic["Value"]) if i.node_name == NODE]
            assert mine, f"{name}: the node publishes no {topic['Value']}"
            qos = mine[0].qos_profile
            if topic.get("Reliability Policy") == "Reliable":
                assert qos.reliability == ReliabilityPolicy.RELIABLE, f"{name}: the node's is {qos.reliability!r}"
            if topic.get("Durability Policy") == "Transient Local":
                assert qos.durability == DurabilityPolicy.TRANSIENT_LOCAL, f"{name}: the node's is {qos.durability!r}"

        frames = urdf_links(description[-1].data)
        frames |= {odometry[-1].header.frame_id, odometry[-1].child_frame_id, poses[-1].header.frame_id}
        assert rviz_frames(config) <= frames, f"RViz frames the node has not: {rviz_frames(config) - frames}"
        assert foxglove_frames(layout) <= frames, f"Foxglove frames the node has not: {foxglove_frames(layout) - frames}"
        assert config["Visualization Manager"]["Global Options"]["Fixed Frame"] == odometry[-1].header.frame_id
    finally:
        stop(node)


URDF_1 = '<robot name="a"><link name="base_link"/></robot>'
URDF_2 = '<robot name="b"><link name="base_link"/><link name="tractor"/></robot>'
REFUSAL = "Unable to initialize urdf::model from robot description"


@pytest.mark.dds
def test_rsp_feed_sets_each_new_description_on_robot_state_publisher_in_its_namespace(tmp_path, probe):
    """A stand-in for robot_state_publisher in /unit1 (its parameter, and its refusal of what is
    no URDF); the latched description is there before the feed starts, as when the simulator
    starts first."""
    target = rclpy.create_node("robot_state_publisher", namespace="unit1", context=probe.context)
    target.declare_parameter("robot_description", "<robot name='placeholder'><link name='x'/></robot>")

    def check(changes):
        bad = [p for p in changes if p.name == "robot_description" and not p.value.startswith("<robot")]
        return SetParametersResult(successful=not bad, reason=REFUSAL if bad else "")

    target.add_on_set_parameters_callback(check)
    probe.executor.add_node(target)
    publisher = probe.node.create_publisher(String, "/unit1/robot_description", DESCRIPTION_QOS)
    publisher.publish(String(data=URDF_1))
    log = tmp_path / "feed.log"
    feed = subprocess.Popen([sys.executable, "-m", "mta_sim_ros.cli", "rsp_feed", "--ros-args", "-r", "__ns:=/unit1"],
                            env=ros_env(), stdout=log.open("w"), stderr=subprocess.STDOUT, cwd=REPO)

    def description():
        return target.get_parameter("robot_description").value

    try:
        assert probe.spin_until(lambda: description() == URDF_1, 60.0), log.read_text()[-2000:]
        publisher.publish(String(data="not a robot"))
        assert probe.spin_until(lambda: REFUSAL in log.read_text(), 30.0), log.read_text()[-2000:]
        assert description() == URDF_1
        assert "robot_state_publisher refused the robot_description: " + REFUSAL in log.read_text()
        publisher.publish(String(data=URDF_2))
        assert probe.spin_until(lambda: description() == URDF_2, 30.0), log.read_text()[-2000:]
    finally:
        assert stop(feed) == 0, log.read_text()[-2000:]
        probe.executor.remove_node(target)
        target.destroy_node()
