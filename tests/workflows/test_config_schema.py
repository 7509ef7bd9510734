"""The configuration schema: one definition of keys, defaults, units and bounds."""

from __future__ import annotations

import dataclasses
import pathlib
import re

import pytest

from bedstruct.cli import main
from bedstruct.errors import ConfigError
from bedstruct.workflows import DEFAULTS, load_config
from bedstruct.workflows.schema import SECTIONS, WorkflowConfig, config_reference, typed_config

DOCS = pathlib.Path(__file__).resolve().parents[2] / "docs" / "workflows.md"


def test_defaults_come_from_the_schema_and_every_key_says_what_it_is():
    assert list(DEFAULTS) == [f.name for f in dataclasses.fields(WorkflowConfig)]
    for name, cls in SECTIONS.items():
        assert list(DEFAULTS[name]) == [f.name for f in dataclasses.fields(cls)]
        for f in dataclasses.fields(cls):
            assert f.metadata["doc"], f"{name}.{f.name} has no meaning"
    # lengths in metres, energy densities in J/m^3: SI inside
    units = {f.name: f.metadata["unit"] for f in dataclasses.fields(SECTIONS["spread"])}
    assert units["gaps"] == "m" and units["speed"] == "m/s" and units["bevel_deg"] == "deg"


@pytest.mark.parametrize("assignment, key, words", [
    ("contact.friction=-0.1", "contact.friction", ">= 0"),
    ("contact.restitution=1.5", "contact.restitution", "<= 1"),
    ("contact.cohesion=-4e6", "contact.cohesion", "J/m^3"),
    ("material.poisson_ratio=0.5", "material.poisson_ratio", "< 0.5"),
    ("psd.fines_mass_fraction=1", "psd.fines_mass_fraction", "< 1"),
    ("contact.rolling_model=foo", "contact.rolling_model", "one of epsd, epsd2, cdt"),
    ("contact.rolling_stiffness_factor=0", "contact.rolling_stiffness_factor", "positive"),
    ("spread.vibration_frequency=-1", "spread.vibration_frequency", "Hz"),
    ("spread.bevel_deg=90", "spread.bevel_deg", "deg"),
])
def test_physical_bounds_are_enforced_with_the_unit(assignment, key, words):
    with pytest.raises(ConfigError, match=re.escape(key) + ".*" + re.escape(words)):
        load_config(preset="tiny", overrides=[assignment])


def test_typed_config_is_read_only_and_equal_to_the_dict():
    cfg = load_config(preset="small", overrides=["spread.speed=0.05"])
    typed = typed_config(cfg)
    assert typed.spread.speed == 0.05 and typed.spread.gaps == tuple(cfg["spread"]["gaps"])
    assert dataclasses.asdict(typed)["contact"] == cfg["contact"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        typed.spread.speed = 1.0


def test_run_help_config_lists_the_workflow_keys_with_defaults_and_units(capsys):
    with pytest.raises(SystemExit) as e:
        main(["run", "spread", "--help-config"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert re.search(r"^\s+gaps\s+\[0\.000508, 0\.000508, 0\.000102, 0\.000127\] m\s", out, re.M)
    assert re.search(r"^\s+speed\s+0\.0254 m/s\s+tool speed", out, re.M)
    assert "[repose]" not in out  # the spread command lists the spreading keys, not repose's
    with pytest.raises(SystemExit):
        main(["run", "repose", "--help-config"])
    assert "[repose]" in capsys.readouterr().out


def test_the_docs_reference_is_the_generated_one():
    text = DOCS.read_text()
    block = text.split("<!-- config-reference:start -->\n")[1].split("<!-- config-reference:end -->")[0]
    assert block == config_reference(markdown=True).replace("### `", "#### `"), \
        "docs/workflows.md's configuration reference is stale: regenerate it with config_reference(markdown=True)"
