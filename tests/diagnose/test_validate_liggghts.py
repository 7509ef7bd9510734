"""The LIGGGHTS-twin validation's orchestration, with both engines stood in for by the
surrogate (the real LIGGGHTS twin end to end is in test_external_twins.py): the plan, the
out-of-catalogue second diagnosis, the reuse of finished twins and records, and the scores
of a twin whose LIGGGHTS model has no magnitude in the catalogue's terms."""

from __future__ import annotations

import importlib
import json

import pytest

import bedstruct.diagnose.engine_simulator as engine_simulator
import bedstruct.diagnose.validation.liggghts_twins as external_twins
from bedstruct.diagnose import (BASE_PARAMETERS, Observations, SurrogateSimulator, validate,
                                validation_report)
from bedstruct.diagnose.validation.records import METHOD_VERSION
from bedstruct.errors import ConfigError

# the package's ``validate_liggghts`` is the function; the tests patch its module
vl = importlib.import_module("bedstruct.diagnose.validation.liggghts")

#: What each LIGGGHTS twin's options stand for on the surrogate (the capillary twin's
#: humidity is the stand-in's, as LIGGGHTS' model has none).
_AS_CATALOGUE = {"contact.rolling_model": {"non_sphericity": 0.20},
                 "contact.capillary": {"capillary_bridges": 0.5},
                 "contact.wall_friction": {"wall_friction": 0.30}}


def _as_catalogue(effects):
    out = {}
    for key, stand_in in _AS_CATALOGUE.items():
        if effects.get(key):
            out.update(stand_in)
    return out


class _StandIn(SurrogateSimulator):
    """The surrogate with the attributes validate_liggghts reads from an engine simulator."""
    preset, overrides, cache, n_cached = "tiny", [], None, 0

    def __init__(self, design, fixed=None):
        super().__init__(design)
        self.fixed = dict(fixed or {})
        self.n_runs = 0

    def __call__(self, base, effects, seed):
        self.n_runs += 1
        return super().__call__(base, {**effects, **self.fixed}, seed)


@pytest.fixture
def stand_ins(monkeypatch):
    made = []

    def fake_liggghts(design, effects, **kw):
        made.append(_StandIn(design, _as_catalogue(effects)))
        return made[-1]

    monkeypatch.setattr(vl.shutil, "which", lambda name: "/usr/bin/" + name)
    monkeypatch.setattr(engine_simulator, "diagnosis_simulator", lambda design, cfg: _StandIn(design))
    monkeypatch.setattr(external_twins, "liggghts_simulator", fake_liggghts)
    return made


def test_plan_covers_null_and_three_liggghts_models():
    from bedstruct.engines import dialect
    from bedstruct.workflows import load_config
    from bedstruct.workflows.external import effects_dialect
    from bedstruct.diagnose.engine_simulator import with_options
    plan = vl.liggghts_twin_plan()
    assert [t.kind for t in plan] == ["null", "effect", "effect", "effect"]
    assert plan[0].effects == {} and plan[0].label == "none"
    # the whole coefficients: the base's, changed by the catalogue's magnitudes
    mu, mu_r = BASE_PARAMETERS["friction"], BASE_PARAMETERS["rolling_friction"]
    assert plan[1].effects == {"contact.rolling_friction": pytest.approx(mu_r + 0.2),
                               "contact.rolling_model": "epsd2"}
    assert plan[3].effects == {"contact.wall_friction": pytest.approx(mu + 0.3)}
    for t in plan:     # every twin's effect is one LIGGGHTS realises on the tiny preset
        dialect("liggghts").check_effects(with_options(load_config(preset="tiny"), t.effects),
                                          spreading=True)
    # the liquid-bridge twin: liquid fraction 5e-4 and 20 degrees per type on the tiny preset
    ov = [f"{k}={v!r}".replace("True", "true") for k, v in plan[2].effects.items()]
    bridges = effects_dialect(load_config(preset="tiny", overrides=["engine=liggghts", *ov])
                              ).liquid_bridges
    assert bridges.lines(2)[0].endswith("surfaceLiquidContentInitial scalar 0.0005")
    assert bridges.lines(2)[3].endswith("contactAngle peratomtype 20 20")
    assert bridges.surface_tension == 1e-3


def test_a_twin_made_by_deck_rewriting_is_refused_by_name(stand_ins, tmp_path):
    old = tmp_path / "twins" / "twin2"
    old.mkdir(parents=True)
    (old / "truth.json").write_text(json.dumps({"effect": {"kind": "capillary"}, "seeds": [1000]}))
    (old / "twin.toml").write_text("")
    with pytest.raises(ConfigError, match="twin2.*deck rewriting.*'capillary'.*Remove the folder"):
        vl.validate_liggghts("tiny", workdir=tmp_path / "twins", refine=0)
    assert stand_ins == []                                # refused before any run


def test_validation_scores_resumes_and_reuses_twins(stand_ins, tmp_path):
    records = tmp_path / "records.jsonl"
    res = vl.validate_liggghts("tiny", workdir=tmp_path / "twins", records=records, refine=0)
    assert res.simulator == "liggghts"
    # 4 twins, the 3 effect twins diagnosed again with their effect removed
    kinds = sorted(t["type"] for t in res.twins)
    assert kinds == ["effect"] * 3 + ["null"] + ["out_of_catalogue"] * 3
    by = {(t["twin"], t["type"]): t for t in res.twins}
    assert by[0, "null"]["verdict"] == "none"
    assert by[1, "effect"]["predicted"].split("+")[0] == "non_sphericity"
    # the capillary twin has no true magnitude: its attribution counts, its interval is not scored
    assert by[2, "effect"]["true_magnitude"] is None
    assert all(m["effect"] != "capillary_bridges" for m in res.magnitudes)
    assert res.top1_accuracy == pytest.approx(
        sum(by[i, "effect"]["predicted"].split("+")[0] == by[i, "effect"]["true_effect"]
            and by[i, "effect"]["verdict"] == "attributed" for i in (1, 2, 3)) / 3)
    def liggghts_runs():
        return sum(sim.n_runs for sim in stand_ins)

    assert liggghts_runs() == 4 * 3                      # one "LIGGGHTS" run per repetition
    truth = json.loads((tmp_path / "twins" / "twin1" / "truth.json").read_text())
    assert truth["seeds"] == [1000, 1001, 1002] and truth["method_version"] == METHOD_VERSION
    assert len(records.read_text().splitlines()) == 7
    # the report the CLI writes (--out)
    from bedstruct.report._render import write_report
    html, _ = write_report(validation_report(res), tmp_path / "report")
    assert "liggghts" in html.read_text(encoding="utf-8")

    # a second run takes every record as done and remakes no twin
    again = vl.validate_liggghts("tiny", workdir=tmp_path / "twins", records=records, refine=0)
    assert liggghts_runs() == 12 and again.settings["resumed_twins"] == 7
    assert [m["seeds_used"] for m in again.settings["twins_made"]] == [[1000, 1001, 1002]] * 4
    assert again.top1_accuracy == res.top1_accuracy

    # without the records, the finished twins are reused (no new LIGGGHTS runs), and a
    # twin whose settings changed is remade
    doc = json.loads((tmp_path / "twins" / "twin0" / "truth.json").read_text())
    doc["noise_seed"] = -1
    (tmp_path / "twins" / "twin0" / "truth.json").write_text(json.dumps(doc))
    third = vl.validate_liggghts("tiny", workdir=tmp_path / "twins", refine=0)
    assert liggghts_runs() == 12 + 3
    assert [t["predicted"] for t in third.twins] == [t["predicted"] for t in res.twins]


def test_a_twin_reading_outside_measured_ranges_is_diagnosed(stand_ins, tmp_path, monkeypatch):
    # an empty end region reads a packing fraction near 0 (here, with noise, below): a
    # twin's number, which the plausible ranges of measured files would refuse
    class EmptyEnd(_StandIn):
        def __call__(self, base, effects, seed):
            obs = super().__call__(base, effects, seed)
            return Observations({**obs.values, "packing_fraction_x1_end": [-0.002]}, obs.source)

    null = vl.liggghts_twin_plan()[:1]
    monkeypatch.setattr(vl, "liggghts_twin_plan", lambda base=None: null)
    monkeypatch.setattr(external_twins, "liggghts_simulator",
                        lambda design, effects, **kw: EmptyEnd(design))
    res = vl.validate_liggghts("tiny", workdir=tmp_path / "twins", refine=0)
    assert [t["type"] for t in res.twins] == ["null"] and not res.settings.get("failed")
    assert 'name = "packing_fraction_x1_end"' in (tmp_path / "twins" / "twin0" / "twin.toml").read_text()


def test_bad_requests_are_clear_errors(stand_ins, monkeypatch):
    with pytest.raises(ConfigError, match="small.*hours"):
        vl.validate_liggghts("small")
    with pytest.raises(ConfigError, match="same scale model"):
        vl.validate_liggghts("tiny", engine={"preset": "small"})
    with pytest.raises(ConfigError, match="twin_repeats"):
        validate("tiny", simulator="liggghts", twin_repeats=3)
    monkeypatch.setattr(vl.shutil, "which", lambda name: None)
    with pytest.raises(ConfigError, match="apt-get install liggghts"):
        vl.validate_liggghts("tiny")
