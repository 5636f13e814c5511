"""Hostile files at every border that reads one: train and scene files (`mta check`), the node's
params file (`mta node --params-file`) and a bag's metadata (`mta analyze`, `mta replay
--resimulate`). Each bad input is one case: exit code 2 (1 where documented), one line naming the
field, the value and the rule, no traceback, quickly; a bag names no file that is ever opened."""
from __future__ import annotations

from pathlib import Path

import pytest

from hostile import CONFIG, assert_refused, forge_bag, mta, recorded_run
from mta_sim_ros.bag import BagWriter

pytestmark = pytest.mark.slow  # a process of its own for every case

TRAIN = (CONFIG / "trains" / "default.yaml").read_text()
SCENE = (CONFIG / "scenes" / "headland_turn.yaml").read_text().replace(
    "train: ../trains/default.yaml", f"train: {CONFIG / 'trains' / 'default.yaml'}")


def alias_bomb(levels: int = 9, width: int = 9) -> str:
    """The 'billion laughs': each level a list of ``width`` aliases of the one before (1.2 KB)."""
    lines = ["a0: &a0 [" + ", ".join(["lol"] * width) + "]"]
    for i in range(1, levels):
        lines.append(f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * width) + "]")
    return "\n".join(lines) + "\n"


def big_table(megabytes: int) -> str:
    """A scene whose steering table takes ``megabytes`` MB."""
    n = megabytes * 1_000_000 // 4
    return SCENE.split("steering:")[0] + "steering:\n  table:\n    time: [" + ",0.1" * n + "]\n"


def swap(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


def train_with(old: str, new: str) -> str:
    return swap(TRAIN, old, new)


def scene_with(old: str, new: str) -> str:
    return swap(SCENE, old, new)


def steered(steering: str) -> str:
    """The scene with ``steering`` (a YAML block) for its own."""
    start, end = SCENE.index("\nsteering:\n") + 1, SCENE.index("\nspeed:\n") + 1
    return SCENE[:start] + steering + SCENE[end:]


SINE = "steering:\n  maneuver: sine\n  params: {amplitude: 0.1, period: 6, cycles: 1}\n"

#: (id, file text (str or bytes), texts the one line must hold)
FILE_FAULTS = [
    ("int-beyond-float", scene_with("duration: 70", "duration: 1" + "0" * 400), ["duration: 1000", "a finite number"]),
    ("int-5000-digits", train_with("mass: 16000", "mass: 1" + "0" * 5000), ["mass: 1000", "(5001 characters)", "finite"]),
    ("float-overflow", train_with("mass: 16000", "mass: 1e999"), ["mass: inf", "a finite number"]),
    ("nan", train_with("mass: 16000", "mass: .nan"), ["mass: nan", "a finite number"]),
    ("nested-2000", "a: " + "[" * 2000 + "]" * 2000, ["nesting: more than 32 levels", "line 1"]),
    ("nested-mappings", "a:\n" + "".join("  " * i + f"b{i}:\n" for i in range(1, 40)), ["nesting", "at most 32"]),
    ("alias-bomb", alias_bomb(), ["document: more than 100000 values with its aliases expanded"]),
    ("many-aliases", "a: &a 1\nb: [" + ", ".join(["*a"] * 65) + "]\n", ["aliases: more than 64"]),
    ("recursive-alias", "a: &a [1, *a]\n", ["*a: an alias inside its own anchor"]),
    ("64MB-table", big_table(64), ["file: more than 262144 characters", "at most 262144 characters"]),
    ("flat-list", "a: [" + "0," * 120_000 + "0]\n", ["document: more than 100000 values"]),
    ("endless-duration", scene_with("duration: 70", "duration: 1e300"), ["duration: 1e+300", "at most 1e+07 ticks"]),
    ("too-many-steps", scene_with("duration: 70", "duration: 150000").replace("tolerance: 1.0e-6", "step: 0.0001"),
     ["duration: 150000", "at most 1e+08 integrator steps"]),
    ("publish-rate-tiny", scene_with("publish_rate: 50", "publish_rate: 1e-300"), ["publish_rate: 1e-300", "in [1, 1000] Hz"]),
    ("publish-rate-negative", scene_with("publish_rate: 50", "publish_rate: -1"), ["publish_rate: -1", "in [1, 1000] Hz"]),
    ("step-tiny", scene_with("tolerance: 1.0e-6", "step: 1e-9"), ["step: 1e-09", "[2e-06, 0.02] s"]),
    ("tolerance-zero", scene_with("tolerance: 1.0e-6", "tolerance: 0"), ["tolerance: 0 in integrator", "> 0"]),
    ("tolerance-nan", scene_with("tolerance: 1.0e-6", "tolerance: .nan"), ["tolerance: nan in integrator", "a finite number"]),
    ("tolerance-text", scene_with("tolerance: 1.0e-6", "tolerance: small"), ["tolerance: 'small' in integrator", "a number"]),
    ("unknown-scene-key", scene_with("publish_rate: 50", "publish_rte: 50"), ["publish_rte: 50", "did you mean publish_rate?"]),
    ("unknown-train-key", train_with("length: 3.0", "lenght: 3.0"), ["lenght: 3.0", "did you mean length?"]),
    ("repeated-key", train_with("mass: 16000", "mass: 16000\n    mass: 1"), ["mass: given twice", "given once"]),
    ("syntax", "carts: [\n", ["yaml:", "valid YAML syntax"]),
    ("a-list", "- 1\n- 2\n", ["file: a list", "a YAML mapping"]),
    ("empty", "", ["file: empty"]),
    ("not-utf8", b"name: \xff\xfe\n", ["file: unreadable", "UTF-8"]),
    ("nul-character", "name: a\x00b\n", ["yaml: character '\\x00' at position 7", "printable text"]),
    ("python-tag", "a: !!python/object/apply:os.system [echo]\n", ["could not determine a constructor", "valid YAML"]),
    ("two-documents", "a: 1\n---\nb: 2\n", ["yaml:", "another document"]),
    ("date-for-number", train_with("mass: 16000", "mass: 2024-01-01"), ["mass: 2024-01-01", "a number"]),
    ("name-is-a-path", scene_with("name: headland_turn", "name: ../../../tmp/evil"), ["name: '../../../tmp/evil'", "without /"]),
    ("wheelbase-tiny", train_with("length: 3.0", "length: 1e-300"), ["length: 1e-300", "in [0.01, 1000] m"]),
    ("offset-huge", train_with("hitch_offset: 1.5", "hitch_offset: 1e300"), ["hitch_offset: 1e+300", "within +-1000 m"]),
    ("actuator-tiny", train_with("time_constant: 0.2", "time_constant: 1e-300"), ["time_constant: 1e-300", "[0.001, 1e+06] s"]),
    ("gain-huge", train_with("kp: 34000", "kp: 1e300"), ["kp: 1e+300", "<= 1e+09"]),
    ("sine-endless", steered(SINE.replace("cycles: 1", "cycles: 100000")), ["cycles: 100000", "fewer", "more than the 100000"]),
    ("sine-period-tiny", steered(SINE.replace("period: 6", "period: 1e-154")), ["period: 1e-154", "at least 0.001 s"]),
    ("manoeuvre-t0-huge", scene_with("t0: 14", "t0: 1e300"), ["t0: 1e+300", "within +-1e+06"]),
    ("train-is-dev-zero", scene_with(f"train: {CONFIG / 'trains' / 'default.yaml'}", "train: /dev/zero"),
     ["train: '/dev/zero'", "a train file"]),
    ("train-is-a-folder", scene_with(f"train: {CONFIG / 'trains' / 'default.yaml'}", "train: .."),
     ["train: '..'", "a train file"]),
]


@pytest.mark.parametrize("case,text,expected", FILE_FAULTS, ids=[c[0] for c in FILE_FAULTS])
def test_a_bad_train_or_scene_file_is_one_line_and_exit_2(tmp_path, case, text, expected):
    path = tmp_path / f"{case}.yaml"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    line = assert_refused(mta("check", path, timeout=30), *expected)
    assert line.startswith("error: ") and str(path) in line


@pytest.mark.parametrize("case", ["missing", "a-folder"])
def test_a_file_that_is_not_there_or_not_a_file_is_one_line(tmp_path, case):
    path = tmp_path / "nothing.yaml" if case == "missing" else tmp_path
    assert_refused(mta("check", path, timeout=30), "file:", "not found" if case == "missing" else "unreadable")


# -- the node's params file ------------------------------------------------------------------

PARAMS = "/**:\n  ros__parameters:\n    record: false\n"

#: (id, params file text, texts the one line must hold)
PARAMS_FAULTS = [
    ("not-yaml", "/**: [\n", ["yaml:", "valid YAML syntax"]),
    ("a-list", "- 1\n", ["file: a list"]),
    ("empty", "", ["file: empty"]),
    ("section-not-mapping", "/**: 5\n", ["/**: 5", "a mapping with the one key ros__parameters"]),
    ("no-ros-parameters", "/**:\n  params: {record: false}\n", ["ros__parameters"]),
    ("ros-parameters-not-mapping", "/**:\n  ros__parameters: [1]\n", ["ros__parameters: [1]", "a mapping of NAME: VALUE"]),
    ("unknown-name", PARAMS + "    publish_rte: 100.0\n", ["publish_rte: 100.0", "did you mean publish_rate?"]),
    ("other-node", PARAMS.replace("/**", "mta_sm"), ["mta_sm:", "did you mean mta_sim?"]),
    ("int-for-double", PARAMS + "    publish_rate: 100\n", ["publish_rate: 100", "write 100.0"]),
    ("out-of-range", PARAMS + "    publish_rate: 5000.0\n", ["publish_rate: 5000.0", "in [1, 1000]"]),
    ("nan", PARAMS + "    real_time_factor: .nan\n", ["real_time_factor: nan", "a finite number"]),
    ("bad-choice", PARAMS + "    watchdog_action: left\n", ["watchdog_action: 'left'", "one of 'hold', 'straight'"]),
    ("wrong-type", PARAMS + "    marker_rate: 'fast'\n", ["marker_rate: 'fast'", "of type float"]),
    ("huge-int", PARAMS + "    tick_cpu: 1" + "0" * 400 + "\n", ["tick_cpu: 1000", "of type int"]),
    ("step-past-tick", PARAMS + "    publish_rate: 10.0\n    integrator_step: 0.5\n",
     ["integrator_step: 0.5", "1/publish_rate] = [1e-05, 0.1] s"]),
    ("alias-bomb", alias_bomb(), ["document: more than 100000 values"]),
    ("nested-2000", "a: " + "[" * 2000 + "]" * 2000, ["nesting: more than 32 levels"]),
]


def node(*args, timeout: float = 60):
    return mta("node", *args, timeout=timeout)


@pytest.mark.parametrize("case,text,expected", PARAMS_FAULTS, ids=[c[0] for c in PARAMS_FAULTS])
def test_a_bad_params_file_is_refused_before_ros_reads_it(tmp_path, case, text, expected):
    path = tmp_path / "params.yaml"
    path.write_text(text)
    line = assert_refused(node("--params-file", path), *expected)
    assert line.startswith("sim_node: ") and "RCLError" not in line


def test_a_missing_params_file_is_one_line(tmp_path):
    assert_refused(node("--params-file", tmp_path / "nowhere.yaml"), "file: not found", "nowhere.yaml")


def test_every_params_file_of_the_ros_arguments_is_checked(tmp_path):
    good, bad = tmp_path / "good.yaml", tmp_path / "bad.yaml"
    good.write_text(PARAMS)
    bad.write_text(PARAMS + "    marker_rate: -1.0\n")
    assert_refused(node("--params-file", good, "--ros-args", "--params-file", bad), "marker_rate: -1.0", "bad.yaml")


def test_a_renamed_node_takes_only_its_own_sections(tmp_path):
    path = tmp_path / "params.yaml"
    path.write_text(PARAMS.replace("/**", "mta_sim"))
    assert_refused(node("--params-file", path, "--ros-args", "-r", "__node:=sim2"), "mta_sim:", "/**, sim2")


# -- a bag's metadata ------------------------------------------------------------------------


@pytest.fixture(scope="module")
def run_bag(tmp_path_factory) -> Path:
    """A 2 s run of `mta run`, the bag every forged one starts from."""
    return recorded_run(tmp_path_factory.mktemp("hostile_bag"))


def put(**values):
    return lambda meta: meta.update(values)


def drop(key):
    return lambda meta: meta.pop(key)


SECRET = "root:x:0:0"  # what /etc/passwd starts with: nothing of it may show

#: (id, change of the record mta_sim_ros, commands that refuse it, texts the line must hold)
BAG_FAULTS = [
    ("train-alias-bomb", put(train_yaml=alias_bomb()), ("analyze", "replay"), ["document: more than 100000", "recorded train"]),
    ("train-huge", put(train_yaml="a: " + "x" * (1 << 19)), ("analyze", "replay"), ["file: 524291 characters"]),
    ("train-not-yaml", put(train_yaml="carts: [\n"), ("analyze", "replay"), ["yaml:", "recorded train"]),
    ("train-missing", drop("train_yaml"), ("analyze", "replay"), ["train_yaml: (missing)"]),
    ("train-bad-field", put(train_yaml=TRAIN.replace("mass: 16000", "mass: -1")), ("analyze", "replay"),
     ["mass: -1", "recorded train 'default.yaml'"]),
    ("scene-not-yaml", put(scene_yaml="[1, 2"), ("replay",), ["yaml:", "recorded scene"]),
    ("rate-inf", put(rate="inf"), ("replay",), ["rate: 'inf'", "a finite number in [1, 1000] Hz"]),
    ("rate-tiny", put(rate="1e-300"), ("replay",), ["rate: '1e-300'", "in [1, 1000] Hz"]),
    ("rate-text", put(rate="fast"), ("replay",), ["rate: 'fast'", "a number"]),
    ("step-tiny", put(step="1e-300"), ("replay",), ["step: '1e-300'", ">= 1/publish_rate / 10000"]),
    ("step-nan", put(step="nan"), ("replay",), ["step: 'nan'", "a finite number"]),
    ("method", put(method="rk5"), ("replay",), ["method: 'rk5'", "one of euler"]),
    ("clock-offset", put(clock_offset="-inf"), ("replay",), ["clock_offset: '-inf'", ">= 0"]),
    ("algorithm", put(algorithm="x"), ("replay",), ["algorithm: 'x'", "one of 1, 2"]),
    ("fidelity", put(fidelity="magic"), ("replay",), ["fidelity: 'magic'", "one of auto, kinematic"]),
    ("split-kinks", put(split_kinks="maybe"), ("replay",), ["split_kinks: 'maybe'", "one of True, False"]),
]


def run_command(command: str, bag: Path, tmp_path: Path):
    if command == "analyze":
        return mta("analyze", bag, "-o", tmp_path / "report")
    return mta("replay", bag, "--resimulate")


@pytest.mark.parametrize("case,change,commands,expected", BAG_FAULTS, ids=[c[0] for c in BAG_FAULTS])
def test_a_bad_bag_record_is_one_line_and_exit_2(run_bag, tmp_path, case, change, commands, expected):
    bag = forge_bag(run_bag, tmp_path / f"{case}.mcap", change)
    for command in commands:
        assert_refused(run_command(command, bag, tmp_path), *expected, str(bag))
    assert not (tmp_path / "report" / "summary.md").exists()


def test_a_message_logged_past_the_tick_bound_is_refused(run_bag, tmp_path):
    """After the first second every message is at 2^62 ns: re-simulating up to it would not end."""
    bag = forge_bag(run_bag, tmp_path / "far.mcap", lambda meta: None,
                    message_time=lambda t: t if t < 1_000_000_000 else 2**62)
    assert_refused(mta("replay", bag, "--resimulate"), "log time: ", "at most 1e+07 ticks")


@pytest.mark.parametrize("names", [
    {"train_file": ".."},
    {"train_file": "/etc/passwd", "scene_file": "/etc/passwd"},
    {"train_file": "/dev/zero", "scene_file": "/proc/self/mem"},
], ids=["dotdot", "etc-passwd", "devices"])
def test_a_path_a_bag_names_is_never_opened(run_bag, tmp_path, names):
    """Both commands rebuild the run from the bag's own texts: whatever file the record names,
    they work (analyze raised IsADirectoryError on '..') and show nothing of it."""
    bag = forge_bag(run_bag, tmp_path / "named.mcap", put(**names))
    analyzed = mta("analyze", bag, "-o", tmp_path / "report")
    assert analyzed.returncode == 0, analyzed.stderr
    replayed = mta("replay", bag, "--resimulate")
    assert replayed.returncode == 0 and replayed.stdout.strip().endswith("identical"), replayed.stderr
    shown = analyzed.stdout + analyzed.stderr + replayed.stdout + replayed.stderr
    shown += "".join(p.read_text() for p in (tmp_path / "report").rglob("*") if p.suffix in (".md", ".json", ".csv"))
    assert SECRET not in shown


def test_a_recorded_scene_naming_another_train_uses_the_recorded_train(run_bag, tmp_path):
    def elsewhere(meta):
        meta["scene_yaml"] = "\n".join("train: /etc/passwd" if line.startswith("train:") else line
                                       for line in meta["scene_yaml"].splitlines())
    bag = forge_bag(run_bag, tmp_path / "elsewhere.mcap", elsewhere)
    replayed = mta("replay", bag, "--resimulate")
    assert replayed.returncode == 0 and replayed.stdout.strip().endswith("identical"), replayed.stderr
    assert SECRET not in replayed.stdout + replayed.stderr


def test_a_bag_without_the_record_is_exit_1_as_documented(run_bag, tmp_path):
    bag = tmp_path / "plain.mcap"
    with BagWriter(str(bag)) as out:
        out.add_topic("/traction_power", "std_msgs/msg/Float64")
        out.write("/traction_power", {"data": 1.0}, 0)
    assert_refused(mta("replay", bag, "--resimulate"), "no metadata record mta_sim_ros", code=1)
    assert_refused(mta("analyze", bag, "-o", tmp_path / "r"), "no metadata record 'mta_sim_ros'", code=1)


NAMES = ["base_link", "odom", "has space", "tab\there", "new\nline", 'a "quote"', "\x07bell", "n" * 10_000,
         "air_cart_hitch", "tractor_front_wheels"]


@pytest.mark.parametrize("name", NAMES, ids=range(len(NAMES)))
def test_check_refuses_the_cart_names_a_run_refuses(tmp_path, name, capsys):
    """One rule for a cart's name: mta check refuses exactly what mta urdf (and so mta run and the
    node, which build the same robot model) refuses; here the seeder renamed, beside carts named
    tractor and air_cart (air_cart_hitch and tractor_front_wheels are frames those make)."""
    import yaml

    from mta_sim_ros import cli

    data = yaml.safe_load((CONFIG / "trains" / "default.yaml").read_text())

    def renamed(o):
        if isinstance(o, dict):
            return {k: renamed(v) for k, v in o.items()}
        if isinstance(o, list):
            return [renamed(v) for v in o]
        return name if o == "seeder" else o

    train = tmp_path / "train.yaml"
    train.write_text(yaml.safe_dump(renamed(data)))
    scene = tmp_path / "scene.yaml"
    scene.write_text((CONFIG / "scenes" / "straight_pass.yaml").read_text().replace("../trains/default.yaml",
                                                                                     str(train)))
    checked = cli.main(["check", str(train), str(scene)])
    urdf = cli.main(["urdf", "--scene", str(scene)])
    err = capsys.readouterr().err
    assert urdf == 2 and checked == 2, err  # every one of them breaks the frames' rule
    assert all(line.startswith(("error: ", "mta urdf: ")) for line in err.splitlines()), err
