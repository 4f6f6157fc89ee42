"""The transport seam's parameters and names (``params.py``, ``base.resolve_topic_name``): ROS
arguments, YAML-typed values, parameter files with patterns and precedence, remaps. No DDS, no
process: what a node is given before it joins a domain.
"""
from __future__ import annotations

import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import pytest  # noqa: E402

from ambiegen_ros.ros.transport import params as P  # noqa: E402
from ambiegen_ros.ros.transport.base import resolve_topic_name  # noqa: E402


# ---------------------------------------------------------------------------------------------
# parameters (params.py)


def test_param_values_are_yaml_typed():
    args = P.parse_ros_args(["prog", "--ros-args", "-p", "i:=3", "-p", "f:=2.5", "-p", "b:=true",
                             "--param", "s:=hello world", "-p", "l:=[1, 2]", "-p", "q:='7'",
                             "-p", "e:=", "-p", "d:=2024-01-01", "--", "--mine"])
    vals = P.resolve_parameters(args, "/n")
    assert vals == {"i": 3, "f": 2.5, "b": True, "s": "hello world", "l": [1, 2], "q": "7",
                    "e": "", "d": "2024-01-01"}
    assert type(vals["i"]) is int and type(vals["f"]) is float


def test_strip_ros_args_keeps_user_args():
    argv = ["prog", "--a", "--ros-args", "-p", "x:=1", "--", "--b", "--ros-args", "-r", "x:=y"]
    assert P.strip_ros_args(argv) == ["prog", "--a", "--b"]


def test_bad_param_syntax_is_rejected():
    with pytest.raises(P.ParameterError):
        P.parse_ros_args(["--ros-args", "-p", "novalue"])
    with pytest.raises(P.ParameterError):
        P.parse_ros_args(["--ros-args", "-p"])


def test_params_file_patterns_nesting_and_precedence(tmp_path):
    f = tmp_path / "p.yaml"
    f.write_text(
        "/**:\n  ros__parameters:\n    common: 1\n    rate: 5.0\n"
        "gen:\n  ros__parameters:\n    pop: 12\n    ga: {mut: 0.1, cx: {eta: 20}}\n"
        "/demo/gen:\n  ros__parameters:\n    pop: 40\n"
        "demo:\n  '*':\n    ros__parameters:\n      where: wild\n"
        "/**/other:\n  ros__parameters:\n    pop: 99\n")
    root = P.parse_ros_args(["--ros-args", "--params-file", str(f)])
    assert P.resolve_parameters(root, "/gen") == {"common": 1, "rate": 5.0, "pop": 12, "ga.mut": 0.1,
                                                  "ga.cx.eta": 20}
    ns = P.resolve_parameters(root, "/demo/gen")
    assert ns["pop"] == 40 and ns["where"] == "wild" and "ga.mut" not in ns
    assert P.resolve_parameters(root, "/x/y/other")["pop"] == 99
    # order of appearance: a later -p beats the file, an earlier one does not; overrides beat all
    later = P.parse_ros_args(["--ros-args", "-p", "pop:=1", "--params-file", str(f), "-p", "rate:=9"])
    vals = P.resolve_parameters(later, "/gen", overrides={"common": 0})
    assert (vals["pop"], vals["rate"], vals["common"]) == (12, 9, 0)


def test_params_file_errors(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("gen:\n  pop: 3\n")
    with pytest.raises(P.ParameterError):
        P.resolve_parameters(P.parse_ros_args(["--ros-args", "--params-file", str(bad)]), "/gen")
    with pytest.raises(P.ParameterError):
        P.resolve_parameters(P.parse_ros_args(["--ros-args", "--params-file", str(tmp_path / "no")]), "/g")


def test_coerce_parameter_types():
    assert P.coerce_parameter("r", 2, 1.0) == 2.0 and isinstance(P.coerce_parameter("r", 2, 1.0), float)
    assert P.coerce_parameter("l", [1, 2], [0.5]) == [1.0, 2.0]
    assert P.coerce_parameter("x", "anything", None) == "anything"
    for value, default in ((1.5, 1), (True, 1), ("3", 3), (1, True), (3, "s"), (1, [1])):
        with pytest.raises(P.ParameterError, match="parameter"):
            P.coerce_parameter("p", value, default)


def test_remaps_and_name_resolution():
    args = P.parse_ros_args(["--ros-args", "-r", "__node:=renamed", "-r", "other:__ns:=/x",
                             "-r", "chat:=/talk", "-r", "gen:scen:=s2"])
    assert args.node_name_override("gen") == "renamed"
    assert args.namespace_override("gen") is None and args.namespace_override("other") == "/x"
    remaps = args.topic_remaps("gen")
    # rule names are expanded in the node's namespace before comparing, as rcl does
    assert resolve_topic_name("chat", "gen", "/ns", remaps) == "/talk"
    assert resolve_topic_name("/chat", "gen", "/ns", remaps) == "/chat"
    assert resolve_topic_name("/chat", "gen", "/", remaps) == "/talk"
    assert resolve_topic_name("scen", "gen", "/a", remaps) == "/a/s2"
    assert resolve_topic_name("~/state", "gen", "/a") == "/a/gen/state"
    assert resolve_topic_name("/abs/t", "gen", "/a") == "/abs/t"
    for bad in ("", "a//b", "trailing/", "1abc", "~x", "sp ace"):
        with pytest.raises(ValueError):
            resolve_topic_name(bad, "gen", "/")
