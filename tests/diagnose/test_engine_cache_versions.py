"""The engine cache holds observations of one code: an entry written by other code (another
bedstruct version, engine or observation operators) is refused with a message naming what
differs, and the call is simulated again, never answered from it."""

from __future__ import annotations

import json
import pathlib
import shutil
import types

import pytest

import bedstruct.diagnose as dg
import bedstruct.workflows.repose as repose
from bedstruct._version import __version__
from bedstruct.diagnose import MeasurementSet
from bedstruct.diagnose.engine_cache import code_versions, read_entry
from bedstruct.diagnose.engine_simulator import EngineSimulator
from bedstruct.errors import ConfigError

RECORDS = pathlib.Path(__file__).resolve().parents[2] / "docs" / "records"


@pytest.fixture
def counted_repose(monkeypatch):
    calls = []

    def fake_run_repose(cfg, *, out, replicates):
        calls.append(1)
        return types.SimpleNamespace(angle_deg=30.0)
    monkeypatch.setattr(repose, "run_repose", fake_run_repose)
    return calls


def _sim(tmp_path):
    design = MeasurementSet((dg.engine_twin_design()["static_angle"],))
    return EngineSimulator(design, {"preset": "tiny", "cache": str(tmp_path)})


def test_code_versions_name_the_package_the_engine_and_the_observation():
    v = code_versions()
    assert set(v) == {"bedstruct", "engine", "observation"}
    assert v["bedstruct"] == __version__
    assert len(v["engine"]) == len(v["observation"]) == 16
    assert code_versions() == v                     # a hash of the source, not of the moment


def test_an_entry_of_the_same_code_is_reused(tmp_path, counted_repose):
    assert _sim(tmp_path)({}, {}, 0)["static_angle"][0] == 30.0
    again = _sim(tmp_path)
    assert again({}, {}, 0)["static_angle"][0] == 30.0
    assert len(counted_repose) == 1 and again.n_cached == 1
    entry = json.loads(next(tmp_path.glob("*.json")).read_text())
    assert entry["meta"]["versions"] == code_versions()


@pytest.mark.parametrize("part", ["bedstruct", "engine", "observation"])
def test_an_entry_of_other_code_is_refused_and_the_call_simulated_again(tmp_path, counted_repose,
                                                                        caplog, part):
    _sim(tmp_path)({}, {}, 0)
    f = next(tmp_path.glob("*.json"))
    doc = json.loads(f.read_text())
    doc["meta"]["versions"][part] = "0123456789abcdef"
    for entry in doc["observables"].values():     # a stale answer that must not come back
        entry["value"] = [99.0]
    f.write_text(json.dumps(doc))
    with caplog.at_level("WARNING", logger="bedstruct.diagnose.engine_cache"):
        obs = _sim(tmp_path)({}, {}, 0)
    assert obs["static_angle"][0] == 30.0 and len(counted_repose) == 2
    assert f"refused: written by other code ({part} 0123456789abcdef, this code " \
        f"{code_versions()[part]})" in caplog.text
    # the entry is replaced by this code's
    assert json.loads(f.read_text())["meta"]["versions"] == code_versions()


def test_an_entry_without_versions_is_refused(tmp_path, counted_repose, caplog):
    """Entries written before the cache stated its code (such as the committed
    docs/records/small-engine-cache) are not trusted: their code is unknown."""
    sim = _sim(tmp_path)
    committed = sorted((RECORDS / "small-engine-cache").glob("*.json"))[0]
    shutil.copy(committed, tmp_path / committed.name)
    with caplog.at_level("WARNING", logger="bedstruct.diagnose.engine_cache"):
        assert read_entry(sim.cache, committed.stem, sim.versions) == {}
    assert "engine not stated" in caplog.text and "observation not stated" in caplog.text


def test_a_replay_reads_an_entry_of_other_code_as_recorded_and_never_simulates(tmp_path,
                                                                               counted_repose):
    """A replay (re-diagnosing a validation record from its own runs) takes an entry whatever
    code wrote it, and a call it lacks is an error naming the call, not a simulation."""
    _sim(tmp_path)({}, {}, 0)
    f = next(tmp_path.glob("*.json"))
    doc = json.loads(f.read_text())
    doc["meta"]["versions"]["engine"] = "0123456789abcdef"
    for entry in doc["observables"].values():     # the recorded answer, whatever it is
        entry["value"] = [41.0]
    f.write_text(json.dumps(doc))
    design = MeasurementSet((dg.engine_twin_design()["static_angle"],))
    # two worker processes: without the replay, prefetch would run the uncached calls there
    sim = EngineSimulator(design, {"preset": "tiny", "cache": str(tmp_path), "jobs": 2})
    sim.replay = True
    assert sim({}, {}, 0)["static_angle"][0] == 41.0 and len(counted_repose) == 1
    assert sim.prefetch([({}, {}, 1), ({}, {}, 2)]) == 0 and sim.n_calls == 0
    with pytest.raises(ConfigError,
                       match=r"seed=5 has no entry for static_angle \(a replay never runs"):
        sim({}, {}, 5)
    assert len(counted_repose) == 1
    # the entry is left as recorded
    assert json.loads(f.read_text())["meta"]["versions"]["engine"] == "0123456789abcdef"
