import json
from pathlib import Path

import jsonschema
import pytest
import yaml

from botstage.behaviors.kinds import NodeKinds
from botstage.missions.schema import json_schema, parse_type
from botstage.skills.registry import Registry
from tests.test_cli import botstage

SHIPPED = Path("missions/mission.schema.json")


def test_shipped_schema_is_up_to_date() -> None:
    """Regenerate with `botstage schema --builtin > missions/mission.schema.json`."""
    # the skills of botstage's own sets too (listen, converse), as `schema --builtin`; plug-in kinds
    # and Nav2's set (XML's) are not shipped
    assert json.loads(SHIPPED.read_text()) == json_schema(Registry.shipped(), NodeKinds.builtin())


def test_schema_command_prints_it() -> None:
    result = botstage("schema", "--builtin")
    assert result.returncode == 0
    assert json.loads(result.stdout) == json.loads(SHIPPED.read_text())


@pytest.mark.parametrize("mission", sorted(Path("missions/examples").glob("*.yaml")), ids=lambda p: p.stem)
def test_every_mission_validates_against_the_schema(mission: Path) -> None:
    schema = json.loads(SHIPPED.read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    jsonschema.validate(yaml.safe_load(mission.read_text()), schema, cls=jsonschema.Draft202012Validator)


def test_the_schema_catches_what_editors_should_flag() -> None:
    schema = json.loads(SHIPPED.read_text())
    validator = jsonschema.Draft202012Validator(schema)
    bad = {"name": "x", "sped": 2, "machine": {"states": {"a": {"skill": "wiat", "transitons": {}}}}}
    messages = sorted(e.message for e in validator.iter_errors(bad))
    assert any("'sped' was unexpected" in m for m in messages)
    assert any("'wiat' is not one of" in m for m in messages)
    assert any("'transitons' was unexpected" in m for m in messages)


@pytest.mark.parametrize("text", ["flaot", "list[", "dict[str]", "float x", "list[int, int]"])
def test_bad_type_names(text: str) -> None:
    with pytest.raises(ValueError):
        parse_type(text)
