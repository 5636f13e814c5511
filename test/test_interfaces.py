"""tf2_msgs, ackermann_msgs and simulation_interfaces as `make venv` builds them
(tools/build_interfaces.sh), held to upstream.

None has a PyPI wheel: the venv gets them from the definitions in interfaces/ through rosidl.
What cannot drift here is upstream itself:

* the files of interfaces/ are upstream's, byte for byte: their git blob ids are the ones of
  ros2/geometry2 at 646342c6164e837d69460e3d28e7a025396544f6 (branch jazzy, tf2_msgs 0.36.4+) and
  of ros-drivers/ackermann_msgs at f61ddd8978bc1604b8beab958bb057ed344225d0 (branch ros2, 2.0.2+)
  and of ros-simulation/simulation_interfaces at tag 1.5.1 (a3c60ff2, the version Jazzy's
  rosdistro releases: release/jazzy/simulation_interfaces/1.5.1-1);
  the copies installed in the venv's share/ (what the bag writer reads) are the same bytes;
* each type's hash (RIHS01, what rmw compares between publisher and subscription) is Jazzy's, see
  JAZZY_HASHES: what the build installed, what another process announces over DDS, and what
  rosbags (an independent implementation of the hash) computes from the installed definitions;
* a message of each type sent by another process over real DDS arrives field for field;
* the project's CDR serializer (the bag writer) writes the same bytes as rclpy's serialize_message,
  padding included (zero in both when rclpy's buffer starts zeroed: rclpy leaves it unwritten).
"""
from __future__ import annotations

import hashlib
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from mcap.reader import make_reader
from rclpy.serialization import serialize_message
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from mta_sim_ros.bag import BagWriter
from mta_sim_ros.bag.schemas import share_dirs

from cdr_refs import assert_fields, rclpy_message
from dds import REPO, ros_env, start_python, stop

INTERFACES = REPO / "interfaces"

#: Every file of interfaces/ -> the git blob id of the upstream file it is (``git ls-tree`` of the
#: commits named in the module docstring; a blob id is the SHA-1 of "blob <size>\\0" + the bytes).
#: tf2_msgs is complete (its srv and action too, as upstream builds it); LICENSE of tf2_msgs is
#: geometry2's top-level LICENSE, the licence of the package.
UPSTREAM_BLOBS = {
    "tf2_msgs/CMakeLists.txt": "2661fc85d54b5b19cfe6d33e468659870856a942",
    "tf2_msgs/package.xml": "161e8833e4992002d52ec64012f2ae5120fba1fd",
    "tf2_msgs/LICENSE": "d79557eefaf84816a7ce5f6201fa32fac60a69b5",
    "tf2_msgs/msg/TFMessage.msg": "fda1e4d0985406667d26b7b36cbbedc9bb497074",
    "tf2_msgs/msg/TF2Error.msg": "e737b64698facba33e32f9cb934d336c207b20bc",
    "tf2_msgs/srv/FrameGraph.srv": "568d1965fbcb5c24aeba1006958fb7499f1e37fc",
    "tf2_msgs/action/LookupTransform.action": "27d35d4bbb602ab614a87c6be3e90bcd035363c4",
    "tf2_msgs/tfmessage_bridge_mapping_rule.yaml": "27190d3be3c8e9e2846aa462ac54b0c8d05134a4",
    "ackermann_msgs/CMakeLists.txt": "0ff1fdd754d138707f92821b3ee4c190e1d5e6ff",
    "ackermann_msgs/package.xml": "4dd09e77b037208d680f891054ccb6886e4ab502",
    "ackermann_msgs/LICENSE": "bea243a0565dc6d0a72ff6b9d27e18cfdb38de00",
    "ackermann_msgs/msg/AckermannDrive.msg": "2ee2939b4649838409b93ffcc0de1b05181fa9d6",
    "ackermann_msgs/msg/AckermannDriveStamped.msg": "1182106912745e171dfd17995d4b2e9db2a2a32d",
    "simulation_interfaces/CHANGELOG.rst": "408563701d658f3470fbf95046cd79969260c2f6",
    "simulation_interfaces/CMakeLists.txt": "57f072702e4cc275bb645652c04d370ac6810670",
    "simulation_interfaces/LICENSE": "261eeb9e9f8b2b4b0d119366dda99c6fd7d35c64",
    "simulation_interfaces/README.md": "42e5c84de5082c291ff5505c862f13d036dfc4a3",
    "simulation_interfaces/action/SimulateSteps.action": "4ba9ab72acb0e52e09b04326e88f3d77aeebb808",
    "simulation_interfaces/msg/Bounds.msg": "ed16b8924f460dabc48d5f836ae68f7361277cdd",
    "simulation_interfaces/msg/EntityCategory.msg": "63d3c0f0f5706a099d6502912aba473c8a9742b8",
    "simulation_interfaces/msg/EntityFilters.msg": "967ffacda704c3ed800f042bf75805f2ce0fe98b",
    "simulation_interfaces/msg/EntityInfo.msg": "eeb7fdc3a292edb449bc9e16d271788ec82496fa",
    "simulation_interfaces/msg/EntityState.msg": "c1a128dd617fdde50db2ed023df24c57b86fc4a0",
    "simulation_interfaces/msg/NamedPose.msg": "54dec31be08843c7c99b79dc1634a3d6a895fb0b",
    "simulation_interfaces/msg/Resource.msg": "e16aeb2136de95b36c401b38cd698582f9a7b310",
    "simulation_interfaces/msg/Result.msg": "64f3879daecb0eaeeab3b363b8e8bb6c3cb987e3",
    "simulation_interfaces/msg/SimulationState.msg": "24246f7aae53829e307652f4ce1fccb0c0ae8c42",
    "simulation_interfaces/msg/SimulatorFeatures.msg": "1073dee5931dd85e353939187f80bcdb527886f2",
    "simulation_interfaces/msg/SpawnEntity.msg": "845e1e5578626697533ff666426f6cc5949fb60f",
    "simulation_interfaces/msg/SpawnResult.msg": "5b79c962a591b54fa603f971fb8900d0f058a118",
    "simulation_interfaces/msg/Spawnable.msg": "d1f874d5478b51ec5c77e18a15b73514357b705b",
    "simulation_interfaces/msg/TagsFilter.msg": "5d087f72fdd09775d300addf1ba496e0b5fd25db",
    "simulation_interfaces/msg/WorldResource.msg": "b10615e8e1c91e68f2377a2a55e76a7c3c29f1da",
    "simulation_interfaces/package.xml": "ca6b84efb9ab8115403e2cf00cffdf4cb7f4291b",
    "simulation_interfaces/srv/DeleteEntity.srv": "334c92b7c66a1ea1938b1f153460d373d1f2beea",
    "simulation_interfaces/srv/GetAvailableWorlds.srv": "be520edff0752fab1e7e96679564173b42e0d11c",
    "simulation_interfaces/srv/GetCurrentWorld.srv": "7ade9b39aac24c69617ffe2d52314b32d354e7d2",
    "simulation_interfaces/srv/GetEntities.srv": "3cbf707a0d454b942e1b9eeff85987c8e525e485",
    "simulation_interfaces/srv/GetEntitiesStates.srv": "1e18846fb3f4bf1881fd1bd06d9f27150274074c",
    "simulation_interfaces/srv/GetEntityBounds.srv": "3c366402ffc81d094d1d3a0afbfb70957bf11ebf",
    "simulation_interfaces/srv/GetEntityInfo.srv": "09370bc9b502d3d373ecfd1d10dcc8eeeb572ced",
    "simulation_interfaces/srv/GetEntityState.srv": "b054ec26440a62775d242d6f8521f491c5563293",
    "simulation_interfaces/srv/GetNamedPoseBounds.srv": "088b9d3e47e40665aad2341d99c3c7005da39170",
    "simulation_interfaces/srv/GetNamedPoses.srv": "cb9158c42a6250740335509655469a996676521f",
    "simulation_interfaces/srv/GetSimulationState.srv": "9b4cd2cdbc52ac4bbd2e372ed838fa923b041830",
    "simulation_interfaces/srv/GetSimulatorFeatures.srv": "785efa84e2762a9c612e17108b9b201743fa09c3",
    "simulation_interfaces/srv/GetSpawnables.srv": "ad18d0f9d9d1e703755b2ee9d986c65c36439e83",
    "simulation_interfaces/srv/LoadWorld.srv": "c4736d4a31a3e682ff5efbe18f62ad674d57c2f3",
    "simulation_interfaces/srv/ResetSimulation.srv": "a53afd53dc65c42566227e7d7f7ce3cce61c10d7",
    "simulation_interfaces/srv/SetEntityInfo.srv": "d77561e4b7a6af1cc46360c8114295fa011acc06",
    "simulation_interfaces/srv/SetEntityState.srv": "2e42e8b444090d29e7dd679340e0fdea0f1057bf",
    "simulation_interfaces/srv/SetSimulationState.srv": "e5a96044049b675d4e77972008883b95b98d7ba6",
    "simulation_interfaces/srv/SpawnEntities.srv": "677b0a5dc67f2cd86c420007ceed41ae81417f0e",
    "simulation_interfaces/srv/SpawnEntity.srv": "de4696f754635e7af473f7621632504a21e20721",
    "simulation_interfaces/srv/StepSimulation.srv": "6ec13766930f8accaee68db20391931379753d0f",
    "simulation_interfaces/srv/UnloadWorld.srv": "aa0475215397a45cfbc4ff28338bfc25bd81169a",
}

#: RIHS01 type hashes of ROS 2 Jazzy. Computed by Jazzy's own rosidl (rosidl_adapter and
#: rosidl_generator_type_description 4.6.6) from upstream's unmodified .msg files, taken from the
#: git commits named above, against the type descriptions that the Jazzy release of
#: common_interfaces installs (share/geometry_msgs/msg/*.json, ...), not from interfaces/ nor this
#: build. tf2_msgs' two are also what rosbags' own Jazzy type store gives (checked below).
JAZZY_HASHES = {
    "tf2_msgs/msg/TFMessage": "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    "tf2_msgs/msg/TF2Error": "RIHS01_db2485e7d6a0ec75bf087e058ee45df682acc3a621ca7780503d10aac141809a",
    "ackermann_msgs/msg/AckermannDrive": "RIHS01_acf287a224a947dd1b0b87d6d76cdb73f497b0237b8fc73be2173b2ebbb82c99",
    "ackermann_msgs/msg/AckermannDriveStamped": "RIHS01_48ca7612a08d3bb72744fd98b71b7cf2ea24c6ad50fa4e1aa0bbad963c90d8cf",
}

#: The same, of the service and the action of tf2_msgs (built as upstream builds the package).
JAZZY_SRV_ACTION_HASHES = {
    "tf2_msgs/srv/FrameGraph": "RIHS01_0d1fbc6222c018ba5f33822904a2fdd4063705289956d3fdde07cd8c50fe8067",
    "tf2_msgs/action/LookupTransform": "RIHS01_0b8adf6bc0b5958879e3265b41a457e03558fe523890a81252c70eba97a82c5d",
}


def blob_id(data: bytes) -> str:
    return hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()


def installed_share(pkg: str) -> Path:
    """The package's share dir where the bag writer looks (in the venv: sys.prefix/share, where
    the build installed it; on a ROS install, the system's)."""
    found = [share / pkg for share in share_dirs() if (share / pkg).is_dir()]
    assert found, f"{pkg} is not installed under any of {share_dirs()} (make venv builds it)"
    return found[0]


def test_interface_files_are_upstream_byte_for_byte():
    found = {p.relative_to(INTERFACES).as_posix(): blob_id(p.read_bytes())
             for p in sorted(INTERFACES.rglob("*")) if p.is_file()}
    assert found == UPSTREAM_BLOBS


@pytest.mark.parametrize("rel", [r for r in UPSTREAM_BLOBS if r.endswith((".msg", ".srv", ".action"))])
def test_the_installed_definitions_are_the_same_bytes(rel):
    """The bag writer's schemas come from share/<pkg>/<kind>/<Name>.<kind> (bag/schemas.py)."""
    pkg, rest = rel.split("/", 1)
    assert (installed_share(pkg) / rest).read_bytes() == (INTERFACES / rel).read_bytes()


def test_the_built_types_import_with_the_fields_of_their_definitions():
    from ackermann_msgs.msg import AckermannDrive, AckermannDriveStamped
    from tf2_msgs.msg import TF2Error, TFMessage

    assert TFMessage.get_fields_and_field_types() == {"transforms": "sequence<geometry_msgs/TransformStamped>"}
    assert TF2Error.get_fields_and_field_types() == {"error": "uint8", "error_string": "string"}
    assert (TF2Error.NO_ERROR, TF2Error.TRANSFORM_ERROR) == (0, 6)
    assert AckermannDrive.get_fields_and_field_types() == {
        name: "float" for name in ("steering_angle", "steering_angle_velocity", "speed", "acceleration", "jerk")}
    assert AckermannDriveStamped.get_fields_and_field_types() == {
        "header": "std_msgs/Header", "drive": "ackermann_msgs/AckermannDrive"}


@pytest.mark.parametrize("type_name", sorted(JAZZY_HASHES | JAZZY_SRV_ACTION_HASHES))
def test_the_build_installed_the_jazzy_type_hash(type_name):
    pkg, kind, name = type_name.split("/")
    description = json.loads((installed_share(pkg) / kind / f"{name}.json").read_text())
    expected = (JAZZY_HASHES | JAZZY_SRV_ACTION_HASHES)[type_name]
    assert description["type_hashes"][0] == {"type_name": type_name, "hash_string": expected}


@pytest.mark.parametrize("type_name", sorted(JAZZY_HASHES))
def test_rosbags_computes_the_jazzy_type_hash_from_the_installed_definitions(type_name):
    """rosbags' RIHS01 is its own code; its Jazzy store brings the std_msgs/geometry_msgs types."""
    store = get_typestore(Stores.ROS2_JAZZY)
    for pkg in ("tf2_msgs", "ackermann_msgs"):
        for path in sorted((installed_share(pkg) / "msg").glob("*.msg")):
            store.register(get_types_from_msg(path.read_text(), f"{pkg}/msg/{path.stem}"))
    assert store.hash_rihs01(type_name) == JAZZY_HASHES[type_name]


#: The messages of simulation_interfaces the node's services carry (sim_services.py).
SIMULATION_MESSAGES = ["simulation_interfaces/msg/Result", "simulation_interfaces/msg/SimulationState",
                       "simulation_interfaces/msg/SimulatorFeatures"]


@pytest.mark.parametrize("type_name", SIMULATION_MESSAGES)
def test_rosbags_and_the_build_agree_on_the_simulation_interfaces_hashes(type_name):
    """Two implementations of RIHS01 (rosidl's, in the build; rosbags') from upstream's files."""
    pkg, kind, name = type_name.split("/")
    store = get_typestore(Stores.ROS2_JAZZY)
    for path in sorted((installed_share(pkg) / "msg").glob("*.msg")):
        store.register(get_types_from_msg(path.read_text(), f"{pkg}/msg/{path.stem}"))
    description = json.loads((installed_share(pkg) / kind / f"{name}.json").read_text())
    assert description["type_hashes"][0] == {"type_name": type_name, "hash_string": store.hash_rihs01(type_name)}


def test_the_simulation_services_import_with_the_standards_constants():
    from simulation_interfaces.msg import SimulatorFeatures
    from simulation_interfaces.srv import ResetSimulation, StepSimulation

    assert StepSimulation.Request.get_fields_and_field_types() == {"steps": "uint64"}
    assert StepSimulation.Request().steps == 1
    assert (ResetSimulation.Request.SCOPE_STATE, ResetSimulation.Request.SCOPE_ALL) == (2, 255)
    assert (SimulatorFeatures.SIMULATION_RESET, SimulatorFeatures.STEP_SIMULATION_MULTIPLE) == (20, 32)


@pytest.mark.parametrize("type_name", ["tf2_msgs/msg/TFMessage", "tf2_msgs/msg/TF2Error"])
def test_rosbags_jazzy_store_has_the_same_tf2_msgs_hashes(type_name):
    """rosbags ships Jazzy's tf2_msgs definitions (not ackermann_msgs): a second, independent copy."""
    assert get_typestore(Stores.ROS2_JAZZY).hash_rihs01(type_name) == JAZZY_HASHES[type_name]


#: Two transforms (frame names of every length mod 4, so the CDR pads between them), and a drive
#: command whose float32 values are exact in float32.
TF_MESSAGE = {"transforms": [
    {"header": {"stamp": {"sec": 12, "nanosec": 345000000}, "frame_id": "map"}, "child_frame_id": "tractor",
     "transform": {"translation": {"x": 1.5, "y": -2.25, "z": 0.1},
                   "rotation": {"x": 0.0, "y": 0.0, "z": 0.3826834323650898, "w": 0.9238795325112867}}},
    {"header": {"stamp": {"sec": -3, "nanosec": 999999999}, "frame_id": "tractor"}, "child_frame_id": "air_cart",
     "transform": {"translation": {"x": -4.75, "y": 0.0, "z": 1e-300},
                   "rotation": {"x": 0.5, "y": -0.5, "z": 0.5, "w": -0.5}}},
]}
ACKERMANN = {"header": {"stamp": {"sec": 7, "nanosec": 5}, "frame_id": "base_link"},
             "drive": {"steering_angle": 0.25, "steering_angle_velocity": -0.5, "speed": 3.0,
                       "acceleration": -0.125, "jerk": 1024.0}}
MESSAGES = {"tf2_msgs/msg/TFMessage": TF_MESSAGE, "ackermann_msgs/msg/AckermannDriveStamped": ACKERMANN}
TOPICS = {"tf2_msgs/msg/TFMessage": "/tf_probe", "ackermann_msgs/msg/AckermannDriveStamped": "/drive_probe"}

#: Another process publishes each message (built with rclpy from the dicts above) until stopped.
PUBLISHER = f"""
    import sys, time, rclpy
    sys.path.insert(0, "test")
    from cdr_refs import rclpy_message
    MESSAGES = {MESSAGES!r}
    TOPICS = {TOPICS!r}
    rclpy.init()
    node = rclpy.create_node("interfaces_publisher")
    pubs = [(node.create_publisher(type(rclpy_message(t, m)), TOPICS[t], 10), rclpy_message(t, m))
            for t, m in MESSAGES.items()]
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        for pub, msg in pubs:
            if pub.get_subscription_count():
                pub.publish(msg)
        time.sleep(0.05)
"""


@pytest.mark.dds
def test_each_type_crosses_real_dds_intact_with_the_jazzy_hash(tmp_path, probe):
    publisher = start_python(PUBLISHER, tmp_path / "publisher.log")
    try:
        boxes = {t: probe.subscribe(TOPICS[t], type(rclpy_message(t, m))) for t, m in MESSAGES.items()}
        arrived = probe.spin_until(lambda: all(boxes.values()) or publisher.poll() is not None, 60.0)
        assert arrived and all(boxes.values()), (tmp_path / "publisher.log").read_text()
        for type_name, message in MESSAGES.items():
            received = boxes[type_name][0]
            assert received == rclpy_message(type_name, message)
            assert_fields(received, message)
            announced = probe.node.get_publishers_info_by_topic(TOPICS[type_name])
            assert [str(info.topic_type_hash) for info in announced] == [JAZZY_HASHES[type_name]]
    finally:
        stop(publisher)


#: rclpy's serialize_message of each message, in another process whose glibc fills every fresh
#: malloc block with one byte (the tcache off, so no block is handed back unfilled): Fast-CDR writes
#: no alignment padding, it leaves those bytes as the buffer had them.
SERIALIZER = f"""
    import json, sys
    sys.path.insert(0, "test")
    from rclpy.serialization import serialize_message
    from cdr_refs import rclpy_message
    MESSAGES = {MESSAGES!r}
    print(json.dumps({{t: serialize_message(rclpy_message(t, m)).hex() for t, m in MESSAGES.items()}}))
"""


def rclpy_serialized(fill: int) -> dict[str, bytes]:
    env = ros_env()
    env["GLIBC_TUNABLES"] = f"glibc.malloc.perturb={fill ^ 0xFF}:glibc.malloc.tcache_count=0"
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(SERIALIZER)], env=env, cwd=REPO,
                         capture_output=True, text=True, timeout=120, check=True).stdout
    return {t: bytes.fromhex(h) for t, h in json.loads(out.splitlines()[-1]).items()}


@pytest.mark.slow
def test_the_bag_writer_writes_what_rclpy_serializes(tmp_path):
    """What the project will write into bags (bag/writer.py through bag/cdr.py, from the installed
    definitions) is what an rclpy publisher puts on the wire, byte for byte, the padding zero.

    rclpy leaves the padding unwritten: serialized into buffers filled with 0x00 and with 0xAA, the
    bytes that differ are the ones it did not write; they must be the padding (fewer than 8 in a
    row, before an aligned field) and ours zero there, every other byte equal."""
    path = tmp_path / "interfaces.mcap"
    with BagWriter(path) as bag:
        for i, (type_name, message) in enumerate(MESSAGES.items()):
            bag.add_topic(TOPICS[type_name], type_name)
            bag.write(TOPICS[type_name], message, log_time_ns=i)
    with open(path, "rb") as f:
        written = {channel.topic: (schema.name, m.data)
                   for schema, channel, m in make_reader(f).iter_messages(log_time_order=False)}
    zeros, aas = rclpy_serialized(0x00), rclpy_serialized(0xAA)
    for type_name in MESSAGES:
        assert written[TOPICS[type_name]] == (type_name, zeros[type_name])
        unwritten = [i for i, (a, b) in enumerate(zip(zeros[type_name], aas[type_name])) if a != b]
        assert len(aas[type_name]) == len(zeros[type_name]) and unwritten, type_name
        assert all(aas[type_name][i] == 0xAA for i in unwritten)
        for start, end in runs(unwritten):  # each gap ends where a field of 2, 4 or 8 bytes starts
            offset = end - 4  # CDR aligns from after the 4-byte encapsulation header
            alignment = max(a for a in (1, 2, 4, 8) if offset % a == 0)
            assert end - start < alignment, (type_name, start, end)


def runs(positions: list[int]) -> list[tuple[int, int]]:
    """The maximal runs [start, end) of consecutive positions."""
    out: list[tuple[int, int]] = []
    for i in positions:
        if out and out[-1][1] == i:
            out[-1] = (out[-1][0], i + 1)
        else:
            out.append((i, i + 1))
    return out
