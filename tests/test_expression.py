import pytest

from botstage.skills.expression import EvaluationError, ExpressionError, compile_expression

VALUES = {"battery_pct": 15, "estop": False, "robot/mode": "docking", "people": [1, 2, 3], "name": "bot"}


def lookup(key: str) -> object:
    return VALUES[key]


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        ("battery_pct < 20", True),
        ("battery_pct < 20 and not estop", True),
        ("battery_pct >= 20 or estop", False),
        ("robot.mode == 'docking'", True),
        ("len(people) >= 2", True),
        ("2 in people", True),
        ("'x' not in name", True),
        ("10 < battery_pct <= 15", True),
        ("battery_pct * 2 - 10 == 20", True),
        ("max(battery_pct, 50) == 50", True),
        ("people[0] == 1", True),
        ("estop == false and true", True),
        ("-battery_pct < 0", True),
        ("'low' if battery_pct < 20 else 'ok'", "low"),
    ],
)
def test_evaluates(source: str, expected: object) -> None:
    assert compile_expression(source).evaluate(lookup) == expected


def test_names_the_keys_it_reads() -> None:
    expression = compile_expression("battery_pct < 20 and not robot.mode == 'x' and len(people) > true")
    assert expression.keys == {"battery_pct", "robot/mode", "people"}


@pytest.mark.parametrize(
    ("source", "message", "column"),
    [
        ("__import__('os').system('true')", "only these functions can be called", 0),
        ("battery_pct.__class__", None, 0),
        ("(lambda: 1)()", "only these functions", 0),
        ("x = 1", "syntax error", 2),
        ("battery_pct <", "syntax error", None),
        ("[i for i in people]", "'ListComp' is not allowed", 0),
        ("a is None", "unsupported comparison", 0),
        ("", "empty condition", 0),
        ("open('f')", "only these functions", 0),
        ("f'{x}'", "not allowed", 0),
    ],
)
def test_rejects_unsafe_or_malformed_input(source: str, message: str | None, column: int | None) -> None:
    if message is None:
        # dotted names are namespaced keys, never attribute access on objects
        expression = compile_expression(source)
        assert expression.keys == {"battery_pct/__class__"}
        with pytest.raises(KeyError):
            expression.evaluate(lookup)
        return
    with pytest.raises(ExpressionError) as info:
        compile_expression(source)
    assert message in str(info.value)
    if column is not None:
        assert info.value.column == column


def test_type_errors_at_evaluation_are_reported_with_the_source() -> None:
    expression = compile_expression("name > 3")
    with pytest.raises(EvaluationError, match="'name > 3'"):
        expression.evaluate(lookup)
