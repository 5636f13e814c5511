"""A recorded run read back for analysis: the topics the simulator writes, found by the last
component of their names (a node's bag may carry a namespace, ``/unit1/hitch_poses``), as time
series, with the train from the bag's metadata record ``mta_sim_ros`` (key ``train_yaml``), so a
bag is analysed without the files it was run from.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from ..physics.terrain import heading_of
from ..bag import read_messages, read_metadata, summary
from ..messages.topics import RUN_METADATA_TOPIC, RUN_METADATA_TYPE
from ..node.runlog import RECORD, recorded_scene, recorded_scene_name, recorded_train

# The topics the simulator writes, by the last component of their names.
KNOWN = ("hitch_poses", "cart_velocities", "traction_power", "steering_angle", "applied_steering",
         "speed_setpoint", "clock")


class AnalyzeError(ValueError):
    """A bag the analysis cannot use (no train metadata, no poses)."""



@dataclass
class Series:
    """One topic's samples: times (s, absolute log time) and values (rows)."""

    t: np.ndarray
    ns: np.ndarray  # log times, ns (int64)
    values: np.ndarray  # shape (N, ...)


@dataclass
class BagData:
    """What the analysis takes from one bag. Times are absolute log times (s); ``t0`` is the first
    pose's time, the origin of every plot."""

    path: Path
    label: str  # the bag's name in legends and tables (its stem, made unique)
    scene_name: str
    train: Any  # model.spec.Train
    topics: dict[str, str]  # last name component -> full topic name
    messages: dict[str, list[tuple[int, Any]]]  # full topic name -> [(log_time_ns, msg)]
    poses: Series  # A_k (N, n, 2)
    pose_heading: Series  # th_k from the quaternions (N, n)
    com_speed: Series | None = None  # s'_Ck (N, n)
    heading: Series | None = None  # th_k from cart_velocities.position (N, n)
    resistance: Series | None = None  # F_Bk (N, n)
    power: Series | None = None  # W (N,)
    command: Series | None = None  # rad (N,)
    applied: Series | None = None  # rad (N,)
    setpoint: Series | None = None  # m/s (N,)
    notes: list[str] = field(default_factory=list)
    position_error_m: float | None = None  # the run's stated accuracy (its metadata), None: not stated

    @property
    def cart_names(self) -> list[str]:
        return [c.name for c in self.train.carts]

    @property
    def n(self) -> int:
        return len(self.train.carts)

    @property
    def t0(self) -> float:
        return float(self.poses.t[0])

    @property
    def title(self) -> str:
        return f"{self.scene_name} ({self.path.name})"

    def axles(self) -> np.ndarray:
        """B_k = A_k - l_k e_k, (N, n, 2)."""
        l = np.array([c.length for c in self.train.carts])
        th = self.pose_heading.values
        e = np.stack([np.cos(th), np.sin(th)], axis=-1)
        return self.poses.values - l[None, :, None] * e

    def hitch_angles(self) -> np.ndarray:
        """th_{k-1} - th_k wrapped to (-pi, pi], (N, n-1), rad."""
        th = self.pose_heading.values
        return wrap(th[:, :-1] - th[:, 1:])


def wrap(angle):
    """Angle(s) wrapped to (-pi, pi]."""
    return -np.remainder(-np.asarray(angle) + math.pi, 2 * math.pi) + math.pi


def quaternion_yaw(q) -> float:
    """The heading of a geometry_msgs/Quaternion (terrain.heading_of: its yaw, a 3D pose's on a
    height grid too), wrapped to (-pi, pi]."""
    return float(wrap(heading_of(q.x, q.y, q.z, q.w)))


def last_component(topic: str) -> str:
    """The last component of a topic's name: /unit1/hitch_poses -> hitch_poses."""
    return topic.rstrip("/").rsplit("/", 1)[-1]


def _find_topics(names: Iterable[str]) -> tuple[dict[str, str], list[str]]:
    """Map the last component of each known topic to its full name (first in sorted order)."""
    found: dict[str, str] = {}
    notes = []
    for full in sorted(names):
        last = last_component(full)
        if last in KNOWN:
            if last in found:
                notes.append(f"topic {full} ignored: {found[last]} already read as {last}")
            else:
                found[last] = full
    return found, notes


def run_record(path) -> dict[str, str] | None:
    """The run's record ``mta_sim_ros`` (scene, train, method, step, rate, clock_offset, ...): the
    bag's metadata record, else the first message of the node's latched topic ``run_metadata``
    (topics.RUN_METADATA_TOPIC, under any namespace: a bag of another recorder, ros2 bag record or
    a conversion by rosbags, which keep messages but not metadata records); None when neither."""
    import json

    meta = read_metadata(path).get(RECORD)
    if meta:
        return meta
    topics = [t for t, info in summary(path).items()
              if t.rsplit("/", 1)[-1] == RUN_METADATA_TOPIC and info["type"] == RUN_METADATA_TYPE and info["count"]]
    for _, _, msg in read_messages(str(path), sorted(topics)[:1]):
        try:
            record = json.loads(msg.data)
        except ValueError:
            return None
        if isinstance(record, dict) and all(isinstance(k, str) and isinstance(v, str) for k, v in record.items()):
            return record
        return None
    return None


def _train_from_metadata(path: Path) -> tuple[Any, str]:
    """The train (model.spec.Train) and scene name from the bag's run record (run_record): its
    recorded texts, parsed by the loader's rules (runlog.recorded_train); no file it names is
    opened."""
    meta = run_record(path)
    if not meta:
        raise AnalyzeError(f"{path}: no metadata record '{RECORD}' and no {RUN_METADATA_TOPIC} topic: the bag was "
                           "not written by mta run or the mta_sim_ros node, or lost its record (a bag rebuilt by mta "
                           "recover keeps what was written before the cut)")
    if "scene_yaml" in meta:  # the scene's terrain, if any, is on its train (loader.scene_from_data)
        return recorded_scene(meta, str(path)).train, recorded_scene_name(meta, str(path))
    return recorded_train(meta, str(path)), recorded_scene_name(meta, str(path))


def stated_error(path: Path) -> float | None:
    """The run's estimated position error as its bag states it (run/accuracy.py): ``mta run``'s in
    the record mta_sim_ros, the node's in its closing record mta_sim_ros.run; None when neither
    holds a finite number (a bag of an older version, a node cut short)."""
    meta = read_metadata(path)
    for record in ("mta_sim_ros.run", RECORD):
        try:
            value = float(meta.get(record, {}).get("position_error_m", "nan"))
        except ValueError:
            continue
        if math.isfinite(value):
            return value
    return None


def _series(rows: list[tuple[int, Any]], value) -> Series | None:
    if not rows:
        return None
    ns = np.array([t for t, _ in rows], dtype=np.int64)
    return Series(ns / 1e9, ns, np.array([value(m) for _, m in rows], dtype=float))


def load_bag(path: str | os.PathLike, label: str | None = None) -> BagData:
    """Read one bag into a :class:`BagData`.

    Raises:
        BagError: the file is not a readable bag.
        AnalyzeError: no train metadata, or no hitch_poses.
        InputError: the recorded train or scene text breaks a rule (SpecError).
    """
    path = Path(path)
    train, scene_name = _train_from_metadata(path)
    messages: dict[str, list[tuple[int, Any]]] = {}
    for topic, t_ns, msg in read_messages(path):
        messages.setdefault(topic, []).append((t_ns, msg))
    topics, notes = _find_topics(messages)
    if "hitch_poses" not in topics:
        raise AnalyzeError(f"{path}: no hitch_poses topic (topics: {', '.join(sorted(messages)) or 'none'})")
    n = len(train.carts)
    get = lambda name: messages.get(topics.get(name, ""), [])  # noqa: E731
    poses = [(t, m) for t, m in get("hitch_poses") if len(m.poses) == n]
    if len(poses) != len(get("hitch_poses")):
        notes.append(f"{len(get('hitch_poses')) - len(poses)} hitch_poses messages without {n} poses ignored")
    if len(poses) < 2:
        raise AnalyzeError(f"{path}: fewer than 2 hitch_poses messages with {n} poses")
    names = [c.name for c in train.carts]

    def by_cart(field_name):
        def value(m):
            vals = dict(zip(m.name, getattr(m, field_name)))
            return [vals.get(name, math.nan) for name in names]
        return value

    vel = [(t, m) for t, m in get("cart_velocities")]
    data = BagData(
        path=path,
        label=label or path.stem,
        scene_name=scene_name,
        train=train,
        topics=topics,
        messages=messages,
        position_error_m=stated_error(path),
        poses=_series(poses, lambda m: [[p.position.x, p.position.y] for p in m.poses]),
        pose_heading=_series(poses, lambda m: [quaternion_yaw(p.orientation) for p in m.poses]),
        com_speed=_series(vel, by_cart("velocity")),
        heading=_series(vel, by_cart("position")),
        resistance=_series([(t, m) for t, m in vel if len(m.effort) == len(m.name)], by_cart("effort")),
        power=_series(get("traction_power"), lambda m: m.data),
        command=_series(get("steering_angle"), lambda m: m.data),
        applied=_series(get("applied_steering"), lambda m: m.data),
        setpoint=_series(get("speed_setpoint"), lambda m: m.data),
        notes=notes,
    )
    return data
