"""ambiegen_msgs and the pure-Python type layer (ambiegen_ros.ros.types).

Three independent witnesses keep the layer honest:
* Debian's python3-rosidl (the ROS 2 parser itself) must accept every .msg and reject broken ones,
  and must read the same fields and constants as rosbags does;
* mcap-ros2-support (Foxglove's encoder, fed with our MCAP schema text) must produce the same CDR
  bytes as rosbags for random messages of every type;
* RIHS01 hashes of standard types must equal values printed by real Jazzy systems.
"""
from __future__ import annotations

import json
import shutil
import subprocess
import textwrap
import zlib
from pathlib import Path

import numpy as np
import pytest
from mcap_ros2._dynamic import generate_dynamic, serialize_dynamic
from rosbags.interfaces import Nodetype

from ambiegen_ros.ros import types as types_mod
from ambiegen_ros.ros.types import MessageTypeError, TypeRegistry, dds_type_name, get_registry, ros_type_name

ROOT = Path(__file__).resolve().parents[2]
MSG_DIR = ROOT / "ambiegen_msgs" / "msg"
PKG = "ambiegen_msgs"
SYSTEM_PYTHON = "/usr/bin/python3"
INSTALL_HINT = "sudo apt-get install -y python3-rosidl python3-catkin-pkg python3-empy"
EXPECTED_TYPES = {
    "ScenarioHeader", "RobotScenario", "VehicleScenario", "ThermostatScenario",
    "ScenarioResult", "RunStatus", "RunConfig",
}


@pytest.fixture(scope="module")
def reg() -> TypeRegistry:
    return get_registry()


# --- rosidl: the ROS 2 parser as validator -----------------------------------------------------
def _rosidl_python() -> str:
    """The system interpreter with python3-rosidl; a missing tool is a failure, not a skip."""
    if not Path(SYSTEM_PYTHON).exists():
        pytest.fail(f"{SYSTEM_PYTHON} not found; the .msg check needs Debian's python3-rosidl ({INSTALL_HINT})")
    probe = subprocess.run(
        [SYSTEM_PYTHON, "-c", "import rosidl_cli.cli, rosidl_adapter, rosidl_parser.parser"],
        capture_output=True, text=True,
    )
    if probe.returncode != 0:
        pytest.fail(f"python3-rosidl is not installed for {SYSTEM_PYTHON}: {INSTALL_HINT}\n{probe.stderr}")
    return SYSTEM_PYTHON


def _rosidl_translate(msg_files: list[Path], out: Path, package: str = PKG) -> subprocess.CompletedProcess:
    """`rosidl translate --to idl -o OUT PKG DIR:msg/X.msg ...` (Debian ships no `rosidl` script)."""
    args = [f"{f.parent.parent}:msg/{f.name}" for f in msg_files]
    return subprocess.run(
        [_rosidl_python(), "-c", "import sys; from rosidl_cli.cli import main; sys.exit(main())",
         "translate", "--to", "idl", "-o", str(out), package, *args],
        capture_output=True, text=True,
    )


_IDL_DUMP = textwrap.dedent(
    """
    import json, pathlib, sys
    from rosidl_parser import definition as d
    from rosidl_parser.parser import parse_idl_file
    NAMES = {'double': 'float64', 'float': 'float32', 'boolean': 'bool', 'octet': 'byte'}
    def typestr(t):
        if isinstance(t, d.AbstractNestedType):
            inner = typestr(t.value_type)
            if isinstance(t, d.Array):
                return f'{inner}[{t.size}]'
            if isinstance(t, d.BoundedSequence):
                return f'{inner}[<={t.maximum_size}]'
            return inner + '[]'
        if isinstance(t, d.NamespacedType):
            return '/'.join(t.namespaces + [t.name])
        if isinstance(t, d.AbstractString):
            return 'string'
        return NAMES.get(t.typename, t.typename)
    base = pathlib.Path(sys.argv[1])
    out = {}
    for p in sorted(base.rglob('*.idl')):
        idl = parse_idl_file(d.IdlLocator(base, p.relative_to(base)))
        msg = idl.content.get_elements_of_type(d.Message)[0]
        out[msg.structure.namespaced_type.name] = {
            'fields': [[m.name, typestr(m.type)] for m in msg.structure.members],
            'constants': {c.name: c.value for c in msg.constants},
        }
    print(json.dumps(out))
    """
)


def _fieldstr(desc) -> str:
    kind, arg = desc
    if kind == Nodetype.BASE:
        return arg[0]
    if kind == Nodetype.NAME:
        return arg
    (subkind, subarg), length = arg
    inner = subarg[0] if subkind == Nodetype.BASE else subarg
    return f"{inner}[{length}]" if kind == Nodetype.ARRAY else f"{inner}[]"


def test_every_msg_passes_rosidl_and_rosidl_reads_what_rosbags_reads(tmp_path, reg):
    files = sorted(MSG_DIR.glob("*.msg"))
    assert {f.stem for f in files} == EXPECTED_TYPES
    result = _rosidl_translate(files, tmp_path / "idl")
    assert result.returncode == 0, result.stderr
    dump = subprocess.run(
        [_rosidl_python(), "-c", _IDL_DUMP, str(tmp_path / "idl")], capture_output=True, text=True
    )
    assert dump.returncode == 0, dump.stderr
    parsed = json.loads(dump.stdout)
    assert set(parsed) == EXPECTED_TYPES
    for name, spec in parsed.items():
        typename = f"{PKG}/msg/{name}"
        ours = [[field, _fieldstr(desc)] for field, desc in reg.store.fielddefs[typename][1]]
        assert spec["fields"] == ours, name
        assert spec["constants"] == reg.constants(typename), name


@pytest.mark.parametrize(
    "text",
    [
        "float64 goodField\n",  # field names must be lower case
        "uint8 NONE=0\nuint8 LIMIT=300\n",  # constant out of range
        "flaot64 typo\n",  # unknown primitive type
        "string run_id\nstring run_id\n",  # duplicate field
    ],
)
def test_rosidl_rejects_a_broken_msg(tmp_path, text):
    broken = tmp_path / "broken_msgs" / "msg" / "Broken.msg"
    broken.parent.mkdir(parents=True)
    broken.write_text(text)
    result = _rosidl_translate([broken], tmp_path / "idl", package="broken_msgs")
    assert result.returncode != 0, f"rosidl accepted {text!r}"


def test_package_files_declare_an_interface_package():
    xml = (ROOT / "ambiegen_msgs" / "package.xml").read_text()
    assert '<package format="3">' in xml
    assert "<member_of_group>rosidl_interface_packages</member_of_group>" in xml
    cmake = (ROOT / "ambiegen_msgs" / "CMakeLists.txt").read_text()
    for f in MSG_DIR.glob("*.msg"):
        assert f'"msg/{f.name}"' in cmake, f"{f.name} missing from rosidl_generate_interfaces"
    for dep in ("std_msgs", "geometry_msgs", "nav_msgs", "diagnostic_msgs", "builtin_interfaces"):
        assert f"<depend>{dep}</depend>" in xml and dep in cmake


# --- registry -----------------------------------------------------------------------------------
def test_registry_loads_our_types_next_to_jazzy(reg):
    assert set(reg.own_types) == {f"{PKG}/msg/{n}" for n in EXPECTED_TYPES}
    assert reg.has("nav_msgs/msg/OccupancyGrid") and reg.has(f"{PKG}/msg/RobotScenario")
    assert not reg.has(f"{PKG}/msg/Nope")
    assert get_registry() is reg
    assert reg.constants(f"{PKG}/msg/ScenarioResult")["SIM_TIMEOUT"] == 8
    with pytest.raises(MessageTypeError, match="pkg/msg/Type"):
        reg.new("OccupancyGrid")


def test_msgs_dir_from_environment(tmp_path, monkeypatch):
    copy = tmp_path / "msg"
    shutil.copytree(MSG_DIR, copy)
    monkeypatch.setenv(types_mod.MSGS_ENV, str(copy))
    assert types_mod.find_msgs_dir() == copy
    assert TypeRegistry().msg_dir == copy
    monkeypatch.setenv(types_mod.MSGS_ENV, str(tmp_path / "empty"))
    with pytest.raises(FileNotFoundError, match=types_mod.MSGS_ENV):
        types_mod.find_msgs_dir()


def test_unknown_nested_type_is_refused(tmp_path):
    (tmp_path / "Broken.msg").write_text("Missing meta\n")
    with pytest.raises(MessageTypeError, match="ambiegen_msgs/msg/Missing"):
        TypeRegistry(tmp_path)


def test_new_fills_defaults_recursively(reg):
    msg = reg.new(f"{PKG}/msg/RobotScenario")
    assert msg.meta.run_id == "" and msg.meta.seed == 0 and msg.meta.surrogate_valid is False
    assert msg.meta.genome.dtype == np.float64 and msg.meta.genome.size == 0
    assert msg.meta.attribute_names == []
    assert msg.map.data.dtype == np.int8 and msg.map.info.resolution == 0.0
    assert msg.start.pose.orientation.w == 0.0
    assert reg.new("sensor_msgs/msg/Imu").orientation_covariance.shape == (9,)  # fixed array
    a, b = reg.new(f"{PKG}/msg/ScenarioResult"), reg.new(f"{PKG}/msg/ScenarioResult")
    assert a.trajectory is not b.trajectory  # no shared mutable defaults
    with pytest.raises(MessageTypeError, match="genom"):
        reg.new(f"{PKG}/msg/ScenarioHeader", genom=[1.0])


def test_numeric_arrays_are_coerced_or_refused(reg):
    t = f"{PKG}/msg/ThermostatScenario"
    msg = reg.new(t, setpoints=[20, 21.5], durations_min=[60, 75], room_models=[1, 7])
    assert msg.setpoints.dtype == np.float64 and msg.room_models.dtype == np.uint8
    with pytest.raises(ValueError, match="room_models"):
        reg.new(t, room_models=[1, 300])
    with pytest.raises(TypeError, match="durations_min"):
        reg.new(t, durations_min=[60.5])
    # an int64 array assigned later would be written as raw int64 memory: serialize fixes it
    msg.setpoints = np.array([16, 25])
    back = reg.deserialize(reg.serialize(msg, t), t)
    assert back.setpoints.tolist() == [16.0, 25.0]
    assert back.durations_min.tolist() == [60, 75] and back.room_models.tolist() == [1, 7]


# --- CDR against an independent encoder ------------------------------------------------------------
_INTS = {"int8": np.int8, "uint8": np.uint8, "int16": np.int16, "uint16": np.uint16, "int32": np.int32,
         "uint32": np.uint32, "int64": np.int64, "uint64": np.uint64, "byte": np.uint8, "char": np.uint8}
_WORDS = ["", "a", "map", "ü", "héllo wörld", "路径", "x" * 13]


def _random_value(reg, desc, rng, depth=0):
    kind, arg = desc
    if kind == Nodetype.BASE:
        return _random_scalar(arg[0], rng)
    if kind == Nodetype.NAME:
        return _random_message(reg, arg, rng, depth + 1)
    (subkind, subarg), length = arg
    count = length if kind == Nodetype.ARRAY else int(rng.integers(0, 4 if depth else 7))
    if subkind == Nodetype.NAME:
        return [_random_message(reg, subarg, rng, depth + 1) for _ in range(count)]
    return [_random_scalar(subarg[0], rng) for _ in range(count)]


def _random_scalar(base, rng):
    if base == "string":
        return str(rng.choice(_WORDS))
    if base == "bool":
        return bool(rng.integers(0, 2))
    if base in ("float32", "float64"):
        value = float(rng.normal() * 1e3)
        return float(np.float32(value)) if base == "float32" else value
    info = np.iinfo(_INTS[base])
    return int(rng.integers(info.min, info.max, endpoint=True, dtype=np.int64 if info.min < 0 else np.uint64))


def _random_message(reg, typename, rng, depth=0):
    fields = {name: _random_value(reg, desc, rng, depth) for name, desc in reg.store.fielddefs[typename][1]}
    return typename, fields


def _build(reg, node):
    """(typename, plain fields) -> rosbags message via reg.new."""
    typename, fields = node
    values = {}
    for name, value in fields.items():
        if isinstance(value, tuple):
            value = _build(reg, value)
        elif isinstance(value, list) and value and isinstance(value[0], tuple):
            value = [_build(reg, v) for v in value]
        values[name] = value
    return reg.new(typename, **values)


def _plain(node):
    """(typename, fields) -> nested dicts/lists, the input form of mcap-ros2-support."""
    typename, fields = node
    out = {}
    for name, value in fields.items():
        if isinstance(value, tuple):
            value = _plain(value)
        elif isinstance(value, list) and value and isinstance(value[0], tuple):
            value = [_plain(v) for v in value]
        out[name] = value
    return out


SAMPLE_TYPES = sorted(f"{PKG}/msg/{n}" for n in EXPECTED_TYPES) + [
    "nav_msgs/msg/OccupancyGrid", "nav_msgs/msg/Path", "geometry_msgs/msg/PoseStamped",
    "diagnostic_msgs/msg/KeyValue", "std_msgs/msg/String",
]


@pytest.mark.parametrize("typename", SAMPLE_TYPES)
def test_cdr_bytes_equal_mcap_ros2_support(reg, typename):
    schema = reg.msgdef(typename)
    encode = serialize_dynamic(typename, schema)[typename]
    decode = generate_dynamic(typename, schema)[typename]
    rng = np.random.default_rng(zlib.crc32(typename.encode()))
    for _ in range(6):
        node = _random_message(reg, typename, rng)
        msg = _build(reg, node)
        ours = reg.serialize(msg, typename)
        assert isinstance(ours, bytes) and ours[:4] == b"\x00\x01\x00\x00"
        theirs = bytes(encode(_plain(node)))
        assert ours == theirs
        # and both directions decode what the other wrote
        assert reg.serialize(reg.deserialize(memoryview(theirs), typename), typename) == ours
        decoded = decode(ours)
        for name, value in _plain(node).items():
            if not isinstance(value, (dict, list)):
                assert getattr(decoded, name) == value, name


def test_occupancy_grid_and_path_round_trip(reg):
    grid = np.zeros((50, 50), dtype=np.int8)
    grid[0, :] = grid[-1, :] = grid[:, 0] = grid[:, -1] = 100
    msg = reg.new("nav_msgs/msg/OccupancyGrid", data=grid.ravel())
    msg.info.width = msg.info.height = 50
    msg.info.resolution = 1.0
    back = reg.deserialize(reg.serialize(msg, "nav_msgs/msg/OccupancyGrid"), "nav_msgs/msg/OccupancyGrid")
    assert np.array_equal(back.data.reshape(50, 50), grid) and back.info.width == 50
    poses = []
    for i in range(3):
        pose = reg.new("geometry_msgs/msg/PoseStamped")
        pose.pose.position.x = float(i)
        poses.append(pose)
    path = reg.new("nav_msgs/msg/Path", poses=poses)
    data = reg.serialize(path, "nav_msgs/msg/Path")
    assert [p.pose.position.x for p in reg.deserialize(data, "nav_msgs/msg/Path").poses] == [0.0, 1.0, 2.0]


# --- schema text, hashes, DDS names ------------------------------------------------------------------
def test_msgdef_is_rosbag2_concatenation(reg):
    t = f"{PKG}/msg/RobotScenario"
    text = reg.msgdef(t)
    sep = "\n" + "=" * 80 + "\nMSG: "
    parts = text.split(sep)
    assert parts[0] == (MSG_DIR / "RobotScenario.msg").read_text()  # the .msg verbatim, like rosbag2
    names = [p.split("\n", 1)[0] for p in parts[1:]]
    # rosbag2: depth first, each type's dependencies in sorted order, every type once
    assert names == [
        "ambiegen_msgs/ScenarioHeader", "std_msgs/Header", "builtin_interfaces/Time",
        "geometry_msgs/PoseStamped", "geometry_msgs/Pose", "geometry_msgs/Point",
        "geometry_msgs/Quaternion", "nav_msgs/OccupancyGrid", "nav_msgs/MapMetaData",
    ]
    assert parts[1].split("\n", 1)[1] == (MSG_DIR / "ScenarioHeader.msg").read_text()


JAZZY_HASHES = {
    # `ros2 topic info -v` / rmw_zenoh key expressions on Jazzy systems
    "std_msgs/msg/String": "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
    "nav_msgs/msg/OccupancyGrid": "RIHS01_8d348150c12913a31ee0ec170fbf25089e4745d17035792a1ba94d6f0bc0cfc7",
    "action_msgs/msg/GoalStatusArray": "RIHS01_6c1684b00f177d37438febe6e709fc4e2b0d4248dca4854946f9ed8b30cda83e",
}


@pytest.mark.parametrize("typename", sorted(JAZZY_HASHES))
def test_type_hash_matches_jazzy(reg, typename):
    assert reg.type_hash(typename) == JAZZY_HASHES[typename]


def test_own_type_hashes_follow_the_definition(reg, tmp_path):
    hashes = {t: reg.type_hash(t) for t in reg.own_types}
    assert len(set(hashes.values())) == len(hashes)
    assert all(h.startswith("RIHS01_") and len(h) == 7 + 64 for h in hashes.values())
    # comments do not change a type's hash; a field does (and it propagates to users of the type)
    shutil.copytree(MSG_DIR, tmp_path / "msg")
    header = tmp_path / "msg" / "ScenarioHeader.msg"
    header.write_text("# another comment\n" + header.read_text())
    assert TypeRegistry(tmp_path / "msg").type_hash(f"{PKG}/msg/ScenarioHeader") == hashes[f"{PKG}/msg/ScenarioHeader"]
    header.write_text(header.read_text() + "uint32 extra\n")
    changed = TypeRegistry(tmp_path / "msg")
    assert changed.type_hash(f"{PKG}/msg/ScenarioHeader") != hashes[f"{PKG}/msg/ScenarioHeader"]
    assert changed.type_hash(f"{PKG}/msg/RobotScenario") != hashes[f"{PKG}/msg/RobotScenario"]
    assert changed.type_hash(f"{PKG}/msg/RunConfig") == hashes[f"{PKG}/msg/RunConfig"]


def test_dds_type_names(reg):
    assert dds_type_name("nav_msgs/msg/OccupancyGrid") == "nav_msgs::msg::dds_::OccupancyGrid_"
    assert reg.dds_type_name(f"{PKG}/msg/ScenarioResult") == "ambiegen_msgs::msg::dds_::ScenarioResult_"
    assert ros_type_name("std_msgs::msg::dds_::String_") == "std_msgs/msg/String"
    with pytest.raises(ValueError):
        ros_type_name("std_msgs::msg::String")
    with pytest.raises(MessageTypeError):
        reg.dds_type_name(f"{PKG}/msg/Nope")
