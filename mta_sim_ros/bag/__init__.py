"""MCAP logging layer of mta_sim_ros (rosbag2 Jazzy compatible, no rclpy needed).

* :mod:`.schemas`: ``message_definition()``, the ros2msg schema text rosbag2 stores.
* :mod:`.definition`: that text parsed into the fields of each message type.
* :mod:`.cdr`: the CDR serializer driven by it (``encode()``, ``MessageEncoder``), no rclpy.
* :mod:`.template`: ``CdrTemplate``, a message encoded once with slots, filled per message.
* :mod:`.writer`: :class:`BagWriter` and plain-dict message builders.
* :mod:`.reader`: ``read_messages()``, ``read_metadata()``, ``summary()``, and
  ``recover()`` and ``holds_a_message()`` for files cut short by a killed writer.
"""

from .reader import PathRefused, holds_a_message, output_target, read_messages, read_metadata, recover, summary
from .schemas import BagError, MessageDefinitionNotFound, message_definition, schema_name
from .writer import (
    DEFAULT_CHUNK_SIZE,
    DEFAULT_QOS_YAML,
    BagWriter,
    clock,
    float64,
    header,
    joint_state,
    pose_array,
    qos_profiles_yaml,
    stamp,
)

__all__ = [
    "BagError",
    "BagWriter",
    "DEFAULT_CHUNK_SIZE",
    "DEFAULT_QOS_YAML",
    "MessageDefinitionNotFound",
    "PathRefused",
    "clock",
    "float64",
    "header",
    "holds_a_message",
    "joint_state",
    "message_definition",
    "output_target",
    "pose_array",
    "qos_profiles_yaml",
    "read_messages",
    "read_metadata",
    "recover",
    "schema_name",
    "stamp",
    "summary",
]
