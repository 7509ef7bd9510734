"""The workflows read one typed configuration, loaded and checked once per run."""

from __future__ import annotations

import dataclasses

import pytest

from bedstruct.errors import ConfigError
from bedstruct.workflows import (WorkflowConfig, config_dict, load_config, run_repose, run_spread,
                                 typed_config, workflow_config)
from bedstruct.workflows import config as config_module
from bedstruct.workflows.external import run_repose_external

WRITE_ONLY = ["engine=liggghts", "external.write_only=true", "contact.cohesion=0.0"]


@pytest.mark.parametrize("preset", ["tiny", "small", "seed"])
def test_the_typed_config_gives_back_the_loaded_dict(preset):
    cfg = load_config(preset=preset, overrides=["spread.gaps=[1e-4, 2e-4]", "engine=lammps"])
    typed = typed_config(cfg)
    back = config_dict(typed)
    assert back == cfg
    assert list(back) == list(cfg)                      # config.toml keeps its order
    assert all(list(back[s]) == list(cfg[s]) for s in cfg if isinstance(cfg[s], dict))
    assert back["spread"]["gaps"] == [1e-4, 2e-4] and typed.spread.gaps == (1e-4, 2e-4)


def test_workflow_config_loads_a_dict_and_takes_a_workflow_config_as_it_is():
    cfg = load_config(preset="tiny", overrides=["contact.friction=0.3"])
    typed = workflow_config(cfg)
    assert isinstance(typed, WorkflowConfig) and typed.contact.friction == 0.3
    assert workflow_config(typed) is typed
    # a partial mapping is completed from the defaults and its preset, as load_config does
    assert workflow_config({"preset": "tiny", "contact": {"friction": 0.3}}) == typed
    with pytest.raises(TypeError, match="mapping .* or a WorkflowConfig; got str"):
        workflow_config("tiny")


def test_a_dict_changed_after_loading_is_refused_before_anything_runs(tmp_path):
    cfg = load_config(preset="tiny")
    cfg["contact"]["friction"] = -0.1
    with pytest.raises(ConfigError, match=r"`contact\.friction` must be >= 0"):
        run_repose(cfg, out=tmp_path / "repose")
    cfg = load_config(preset="tiny")
    cfg["spread"]["gaps"] = []
    with pytest.raises(ConfigError, match=r"`spread\.gaps` must list at least one layer gap"):
        run_spread(cfg, out=tmp_path / "spread")
    assert not (tmp_path / "repose").exists() and not (tmp_path / "spread").exists()


@pytest.fixture
def validations(monkeypatch):
    """Count the value checks of configuration dicts (config._validate)."""
    calls = []
    real = config_module._validate

    def counted(cfg, *args):
        calls.append(cfg)
        return real(cfg, *args)
    monkeypatch.setattr(config_module, "_validate", counted)
    return calls


def test_a_run_checks_its_configuration_once(tmp_path, validations):
    cfg = load_config(preset="tiny", overrides=WRITE_ONLY)
    assert len(validations) == 1                        # load_config
    run_repose(cfg, out=tmp_path / "dict")
    assert len(validations) == 2                        # the dict, once at the entry point
    run_repose(typed_config(cfg), out=tmp_path / "typed")
    assert len(validations) == 2                        # a WorkflowConfig: not again


def test_a_dict_and_its_workflow_config_write_the_same_decks(tmp_path):
    cfg = load_config(preset="tiny", overrides=WRITE_ONLY + ["contact.friction=0.6"])
    a = run_repose_external(cfg, out=tmp_path / "dict")
    b = run_repose_external(typed_config(cfg), out=tmp_path / "typed")
    deck_a = open(a.decks[0]).read().replace(str(tmp_path / "dict"), "OUT")
    deck_b = open(b.decks[0]).read().replace(str(tmp_path / "typed"), "OUT")
    assert deck_a == deck_b and "0.6" in deck_a
    assert (tmp_path / "dict" / "config.toml").read_text() == \
        (tmp_path / "typed" / "config.toml").read_text()
    # a section changed with dataclasses.replace changes the deck
    typed = typed_config(cfg)
    other = dataclasses.replace(typed, contact=dataclasses.replace(typed.contact, friction=0.2))
    c = run_repose_external(other, out=tmp_path / "replaced")
    deck_c = open(c.decks[0]).read().replace(str(tmp_path / "replaced"), "OUT")
    assert deck_c != deck_a
    assert load_config(tmp_path / "replaced" / "config.toml")["contact"]["friction"] == 0.2
