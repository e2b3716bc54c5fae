"""BehaviorTree.CPP's script language, statement by statement, after BT.CPP's own
tests/script_parser_test.cpp (ParserTest.AnyTypes, AnyTypes_Failing, Equations): the same scripts
run in the same order on one blackboard, with the values and errors BT.CPP gives."""

from __future__ import annotations

from typing import Any

import pytest

from botstage.behaviors.btcpp.script import ScriptError, ScriptRuntimeError, compile_script


class Vars(dict):
    """A blackboard as the script sees it."""

    def exists(self, name: str) -> bool:
        return name in self

    def get(self, name: str, default: Any = None) -> Any:
        return self[name]

    def set(self, name: str, value: Any) -> None:
        self[name] = value


LITERALS = [
    ("628", 628),
    ("0x100", 256),
    ("0X100", 256),
    ("3.14", 3.14),
    ("-3.14", -3.14),
    ("3.14e2", 314.0),
    ("3.14e-2", 0.0314),
    ("3e2", 300.0),
    ("3e-2", 0.03),
    ("'hello world '", "hello world "),
    ('"double quoted"', "double quoted"),
    ("true", 1),
    ("false", 0),
]


@pytest.mark.parametrize(("source", "value"), LITERALS, ids=[s for s, _ in LITERALS])
def test_literals(source: str, value: Any) -> None:
    assert compile_script(source).run(Vars()) == value


# (script, its value or the error it raises, the variables checked afterwards)
EQUATIONS: list[tuple[str, Any, dict[str, Any]]] = [
    ("x:= 3; y:=5; x+y", 8.0, {"x": 3, "y": 5}),
    ("x+=1", 4, {"x": 4}),
    ("x -= 1", 3, {"x": 3}),
    ("x*=2", 6, {"x": 6}),
    ("-x", -6.0, {}),
    ("x/=2", 3, {"x": 3}),
    ("y/2", 2.5, {}),
    ("y-x", 2.0, {}),
    ("y & x", float(5 & 3), {}),
    ("y | x", float(5 | 3), {}),
    ("y ^ x", float(5 ^ 3), {}),
    ("y ^ 5.1", ScriptRuntimeError, {}),
    ("A:='hello'; B:=' '; C:='world'; A+B+C", "hello world", {"A": "hello", "C": "world"}),
    ("A= '   right'; B= ' center '", " center ", {"A": "   right", "B": " center "}),
    ("x=A", ScriptRuntimeError, {"x": 3}),  # can't change the type, once created
    ("x='msg'", ScriptRuntimeError, {"x": 3}),
    ("A=1.0", ScriptRuntimeError, {"A": "   right"}),
    ("new_var=69", ScriptRuntimeError, {}),  # `=` does not create
    ("x < y", 1.0, {}),
    ("y != x", 1.0, {}),
    ("y == x", 0.0, {}),
    ("'hello' < 'world'", 1.0, {}),
    ("'hello' > 'world'", 0.0, {}),
    ("y == x ? 'T' : 'F'", "F", {}),
    ("y != x ? 'T' : 'F'", "T", {}),
    ("x == 3", 1.0, {}),
    ("1 < x < 4", 1.0, {}),  # comparisons chain
    ("v1:= true; v2:= false", 0, {"v1": 1, "v2": 0}),
    ("v2 = !false", 1, {"v2": 1}),
    ("v2 = !v2", 0, {"v2": 0}),
    ("v1 && v2", 0.0, {}),
    ("v1 || v2", 1.0, {}),
    (" y == x  ||  x == 3 ", 1.0, {}),
    ("msg := 'x=' .. x .. ', y/2=' .. y / 2", "x=3, y/2=2.5", {}),
    ("msg += '!'", "x=3, y/2=2.5!", {}),
    ("msg -= 'x'", ScriptRuntimeError, {}),
    ("x == 'three'", ScriptRuntimeError, {}),  # a string that is no number
    ("x == '3'", 1.0, {}),  # a port written in XML is text: read as a number
    ("missing + 1", ScriptRuntimeError, {}),
    ("~x", float(~3), {}),
    ("-'text'", ScriptRuntimeError, {}),
]


def test_equations_as_in_btcpp() -> None:
    variables = Vars()
    for source, expected, after in EQUATIONS:
        script = compile_script(source)
        if expected is ScriptRuntimeError:
            with pytest.raises(ScriptRuntimeError):
                script.run(variables)
        else:
            value = script.run(variables)
            assert value == expected and type(value) is type(expected), source
        for key, value in after.items():
            assert variables[key] == value and type(variables[key]) is type(value), (source, key)


@pytest.mark.parametrize(
    ("source", "column", "message"),
    [
        ("0X100g", 6, "invalid suffix"),
        ("0X100.", 6, "invalid suffix"),
        ("3foo", 2, "invalid suffix"),
        ("65.", 3, "invalid suffix"),
        ("65.43foo", 6, "invalid suffix"),
        ("x := ", 6, "expected a value, found the end of the script"),
        ("'hello' = 'world'", 1, "the left of '=' must be a blackboard key"),
        ("3.0 = 2.0", 1, "the left of '=' must be a blackboard key"),
        ("a := (1 + 2", 12, "expected ')'"),
        ("a := 1 b := 2", 8, "expected ';'"),
        ("a := 'open", 6, "unexpected character"),
        ("a := 1 ? 2", 11, "expected ':'"),
    ],
)
def test_syntax_errors_say_where(source: str, column: int, message: str) -> None:
    with pytest.raises(ScriptError) as caught:
        compile_script(source)
    assert caught.value.column == column and message in caught.value.message


def test_keys_read_and_written_are_known_before_running() -> None:
    script = compile_script("total := @base + step; count += 1; label = 'x'")
    assert script.reads == {"@base", "step", "count"}
    assert script.writes == {"total", "count", "label"}


def test_as_a_condition_strings_must_read_as_booleans() -> None:
    assert compile_script("flag").check(Vars(flag="true")) is True
    assert compile_script("n - 2").check(Vars(n=2)) is False
    with pytest.raises(ScriptRuntimeError):
        compile_script("flag").check(Vars(flag="maybe"))


def test_a_long_script_is_refused() -> None:
    with pytest.raises(ScriptError):
        compile_script("x := " + " + ".join(["1"] * 2000))
