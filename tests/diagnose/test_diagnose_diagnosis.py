"""End to end on the surrogate: the seed file, withheld-effect twins, the tiny validation, the CLI."""

from __future__ import annotations

import json
import pathlib

import numpy as np
import pytest

from bedstruct.cli import main
from bedstruct.diagnose import (BASE_PARAMETERS, SurrogateSimulator, catalogue, compute_fingerprints,
                                diagnose, diagnosis_design, diagnosis_report, load_measurements,
                                validate, validation_report)
from bedstruct.diagnose.validation.scores import capped_twins
from bedstruct.diagnose.validation.twins import _magnitude_for_snr, _twin_measurements, _twin_sigma
from bedstruct.diagnose.validation.design import twin_design

SEED = pathlib.Path(__file__).resolve().parents[2] / "data" / "measurements" / "seed.toml"


@pytest.fixture(scope="module")
def twin_setup():
    eff = catalogue()
    design = diagnosis_design(twin_design(), eff)
    sim = SurrogateSimulator(design)
    fps = compute_fingerprints(sim, design, BASE_PARAMETERS, eff, replicates=3, alpha=0.01)
    return eff, sim, fps


@pytest.fixture(scope="module")
def tiny_serial(tmp_path_factory):
    """``validate("tiny", refine=0)`` run once, serially, into a fresh records file:
    (result, the records' lines, the status lines it said)."""
    whole = tmp_path_factory.mktemp("tiny") / "whole.jsonl"
    statuses = []
    res = validate("tiny", refine=0, records=whole, on_status=statuses.append)
    return res, whole.read_text().splitlines(), statuses


def _twin(sim, fps, tmp_path, effects, seed):
    return _twin_measurements(twin_design(), sim, dict(BASE_PARAMETERS), effects, seed, tmp_path, seed,
                              sim.noise_sd())


def test_twins_are_sized_in_the_noise_their_diagnosis_sees(twin_setup, tmp_path):
    from bedstruct.diagnose.identifiability import nuisance_projector
    eff, sim, fps = twin_setup
    sig = _twin_sigma(fps, sim.noise_sd())
    real = _twin(sim, fps, tmp_path, {}, 3)
    comp = fps.design.component_names()
    n = np.maximum(np.isfinite(fps.base_samples).sum(axis=0), 1)
    # the twin's file states the noise that its diagnosis combines with the base runs' mean
    for m in real:
        i = comp == m.name
        assert np.allclose(np.sqrt(np.asarray(m.uncertainty) ** 2 + fps.sim_var[i] / n[i]), sig[i])
    assert np.all(sig >= fps.sigma) and np.any(sig > 1.2 * fps.sigma)
    # a twin asked for 8 sigma has a projected gap of 8 sigma in that noise
    a = _magnitude_for_snr(fps, "blade_startup", 8.0, sig)
    cal = fps.rows_calibrate
    P = nuisance_projector(fps.sensitivities[cal] / sig[cal, None])
    assert np.linalg.norm(P @ (fps["blade_startup"].predict(a)[cal] / sig[cal])) == pytest.approx(8.0, rel=1e-6)
    assert a > _magnitude_for_snr(fps, "blade_startup", 8.0)  # in the design's noise: weaker


def test_repeated_experiments_state_the_standard_error_of_their_mean(twin_setup, tmp_path):
    eff, sim, fps = twin_setup
    design = twin_design()
    noise = sim.noise_sd()

    def files(repeats, n=40):
        return [_twin_measurements(design, sim, dict(BASE_PARAMETERS), {}, s, tmp_path, s, noise,
                                   repeats) for s in range(100, 100 + n)]

    for repeats in (1, 4):
        twins = files(repeats)
        one = files(1, 1)[0]
        for m in design:
            stated = np.array([t[m.name].uncertainty for t in twins])
            assert np.allclose(stated, one[m.name].uncertainty / np.sqrt(repeats))
        # the values scatter as stated: pooled over components, variance ratio near 1
        ratios = []
        for m in design:
            v = np.array([t[m.name].values for t in twins])
            ratios.extend(v.var(axis=0, ddof=1) / twins[0][m.name].uncertainty ** 2)
        assert np.mean(ratios) == pytest.approx(1.0, abs=0.2)
    # sized in that noise, a twin of repeated experiments needs a smaller magnitude
    four = _twin_sigma(fps, noise, 4)
    assert np.all(four < _twin_sigma(fps, noise))
    assert _magnitude_for_snr(fps, "blade_startup", 8.0, four) < \
        _magnitude_for_snr(fps, "blade_startup", 8.0, _twin_sigma(fps, noise))


def test_a_repeat_that_could_not_observe_leaves_the_mean_of_the_others(twin_setup, tmp_path):
    from bedstruct.diagnose import Observations
    from bedstruct.diagnose.validation.twins import _repeat_seed
    eff, sim, fps = twin_setup
    design = twin_design()
    name = design.measurements[0].name

    def blind_once(base, effects, seed):           # the second experiment sees no heap
        obs = sim(base, effects, seed)
        if seed == _repeat_seed(7, 1):
            obs = Observations(dict(obs.values, **{name: np.full_like(obs[name], np.nan)}))
        return obs

    one = _twin_measurements(design, sim, dict(BASE_PARAMETERS), {}, 7, tmp_path, 7, sim.noise_sd())
    three = _twin_measurements(design, blind_once, dict(BASE_PARAMETERS), {}, 7, tmp_path, 7,
                               sim.noise_sd(), 3)
    assert np.all(np.isfinite(three[name].values))
    assert np.allclose(three[name].uncertainty, one[name].uncertainty / np.sqrt(2))   # two seen
    other = design.measurements[1].name
    assert np.allclose(three[other].uncertainty, one[other].uncertainty / np.sqrt(3))


def test_records_without_a_newer_key_take_its_old_value(tmp_path):
    from bedstruct.diagnose.validation.records import METHOD_VERSION, records_done
    sig = {"preset": "tiny", "method_version": METHOD_VERSION}
    rec = tmp_path / "r.jsonl"
    rec.write_text(json.dumps({"twin": 0, "type": "null", **sig}) + "\n")
    assert records_done(rec, dict(sig, twin_repeats=1))
    assert not records_done(rec, dict(sig, twin_repeats=3))
    assert not records_done(rec, dict(sig, method_version=METHOD_VERSION + 1))


def test_records_written_before_the_method_version_are_read_by_their_fields(tmp_path):
    """Records that name their method by the fields used before ``method_version`` (as those
    in docs/records do) are resumed when those fields are the current method's, not else."""
    from bedstruct.diagnose.validation.records import method_version_of, records_done
    sig = {"preset": "tiny", "method_version": 1}
    current = {"twin_rule": 7, "fit_rule": 14, "scatter_rule": 2}
    rec = tmp_path / "r.jsonl"
    rec.write_text(json.dumps({"twin": 0, "type": "null", "preset": "tiny", **current}) + "\n")
    assert records_done(rec, sig)
    for older in ({"fit_rule": 13}, {"scatter_rule": 1}, {"twin_rule": 6}):
        rec.write_text(json.dumps({"twin": 0, "type": "null", "preset": "tiny",
                                   **dict(current, **older)}) + "\n")
        assert not records_done(rec, sig)
    # a record with none of them is older than all of them
    assert method_version_of({"twin": 0}) is None
    # the committed records of the current method are version 1, the older ones none
    records = pathlib.Path(__file__).resolve().parents[2] / "docs" / "records"
    first = json.loads((records / "small-engine-fit14").glob("*.jsonl").__next__()
                       .read_text().splitlines()[0])
    assert method_version_of(first) == 1
    first = json.loads((records / "small-engine-fit13").glob("*.jsonl").__next__()
                       .read_text().splitlines()[0])
    assert method_version_of(first) is None
    from bedstruct.errors import ConfigError
    with pytest.raises(ConfigError, match="twin_repeats"):
        validate("tiny", twin_repeats=0)


def test_withheld_effect_is_found_with_magnitude(twin_setup, tmp_path):
    eff, sim, fps = twin_setup
    a = _magnitude_for_snr(fps, "blade_startup", 8.0)
    real = _twin(sim, fps, tmp_path, {"blade_startup": a}, 11)
    d = diagnose(real, sim, base=BASE_PARAMETERS, fingerprints=fps)
    assert d.verdict == "attributed" and d.where.significant
    top = d.attribution.selected[0]
    assert top.effect == "blade_startup"
    assert top.interval[0] <= a <= top.interval[1]
    assert d.shrink.after <= d.shrink.before
    # the held-out gap before, tested against noise (chi-square of its standardised residuals)
    from scipy import stats
    n = d.shrink.n_heldout
    assert d.shrink.p_before == pytest.approx(stats.chi2.sf(n * d.shrink.before ** 2, n))
    j = d.to_json()
    assert j["simulator"] == "surrogate" and j["which"][0]["effect"] == "blade_startup"
    assert {"where", "which", "shrink", "next", "confidence"} <= set(j)
    # which effects the design tells apart: each effect's closest imitation by another
    assert [r["effect"] for r in j["separation"]] == [e.name for e in eff]
    assert all(r["other"] != r["effect"] and 0 <= r["unique_fraction"] <= 1 for r in j["separation"])
    fp_section = [s for s in diagnosis_report(d).sections if s.key == "fingerprints"][0]
    assert any("closest imitation by" in t.columns for t in fp_section.tables)
    json.dumps(j, allow_nan=True)


def test_null_twin_shows_no_gap(twin_setup, tmp_path):
    eff, sim, fps = twin_setup
    real = _twin(sim, fps, tmp_path, {}, 21)
    d = diagnose(real, sim, base=BASE_PARAMETERS, fingerprints=fps)
    assert not d.where.significant
    assert d.verdict == "none" and d.to_json()["which"] == []


def test_out_of_catalogue_twin_is_unexplained(twin_setup, tmp_path):
    eff, sim, fps = twin_setup
    a = _magnitude_for_snr(fps, "missing_fines", 8.0)
    real = _twin(sim, fps, tmp_path, {"missing_fines": a}, 31)
    without = [e for e in eff if e.name != "missing_fines"]
    d = diagnose(real, sim, base=BASE_PARAMETERS, effects=without, fingerprints=fps)
    assert d.where.significant
    assert d.verdict == "unexplained" and d.to_json()["which"] == "unexplained"
    # with the effect back in the catalogue the same data are explained
    d2 = diagnose(real, sim, base=BASE_PARAMETERS, fingerprints=fps)
    assert d2.attribution.selected[0].effect == "missing_fines"


def test_seed_measurements_end_to_end():
    ms = load_measurements(SEED)
    eff = catalogue()
    sim = SurrogateSimulator(diagnosis_design(ms, eff))
    d = diagnose(ms, sim, base=BASE_PARAMETERS, replicates=3)
    top = d.where.ranked(1)[0]
    # the simulated PSD is cut at 28 um: the d10 gap dominates, and fines explain it
    assert top["observable"] == "psd_before" and top["component"] == "d10" and top["z"] < -4
    assert d.verdict == "attributed" and d.attribution.selected[0].effect == "missing_fines"
    ident = {r["effect"]: r["identifiable"] for r in d.fingerprints.table()}
    assert ident["contact_ageing"] is False          # the qualitative spike (4 deg) cannot decide it
    assert "avalanche_angle_rest600" in d.to_json()["not_identifiable"][0]["identify_with"]
    assert d.next and not d.next[0].measured
    rep = diagnosis_report(d)
    assert rep.failed == []


def test_tiny_validation_meets_the_goals():
    r = validate("tiny")
    j = r.to_json()
    assert j["simulator"] == "surrogate"
    assert r.top1_accuracy >= 0.9
    assert r.null_false_attribution <= 0.05
    assert r.out_of_catalogue_unexplained >= 0.8
    assert r.median_gap_shrink >= 0.7
    assert r.magnitude_coverage >= 0.7
    m = np.asarray(r.confusion["matrix"])
    assert m.sum() == len(r.twins) == 28
    assert validation_report(r).failed == []
    # scores over identifiable effects: every surrogate effect is identifiable on this design
    ident = j["identifiable"]
    assert ident["effects"] == r.settings["effects"] and ident["not_identifiable"] == []
    assert ident["top1_accuracy"] == r.top1_accuracy and ident["n_effect_twins"] == 12
    # an engine validation's missing data are stated in the report
    from dataclasses import replace
    holes = replace(r, settings=dict(r.settings, missing_runs={"dynamic_angle_x5_early": 3},
                                     unobservable={"psd_after_x1": "not observed in 4 of 20 runs"}))
    goals = [s for s in validation_report(holes).sections if s.key == "goals"][0]
    assert "dynamic_angle_x5_early not observed in 3" in goals.text and "psd_after_x1 dropped" in goals.text
    assert "top1_accuracy_identifiable" not in goals.numbers
    blind = replace(r, identifiable=dict(ident, not_identifiable=["wall_friction"]))
    goals = [s for s in validation_report(blind).sections if s.key == "goals"][0]
    assert "wall_friction" in goals.numbers["top1_accuracy_identifiable"].definition
    # a twin that carries no significant gap is scored apart as well (no method attributes it);
    # the surrogate's twins all carry theirs
    det = j["detected"]
    assert det["n_effect_twins"] == 12 and det["n_effect_twins_undetected"] == 0
    assert det["top1_accuracy"] == r.top1_accuracy
    assert "top1_accuracy_detected" not in goals.numbers
    from bedstruct.diagnose.validation.scores import score_twins
    hit = next(t for t in r.twins if t["type"] == "effect" and t["verdict"] == "attributed"
               and t["predicted"] == t["true_effect"])
    weak = [dict(t, gap_significant=False, verdict="none", predicted="none") if t is hit else t
            for t in r.twins]
    scored = score_twins(weak, r.settings["effects"])
    n_hits = round(r.top1_accuracy * 12)
    assert scored["top1_accuracy"] == pytest.approx((n_hits - 1) / 12)
    assert scored["detected"]["n_effect_twins_undetected"] == 1
    assert scored["detected"]["top1_accuracy"] == pytest.approx((n_hits - 1) / 11)
    goals = [s for s in validation_report(replace(r, detected=scored["detected"])).sections
             if s.key == "goals"][0]
    assert "carry none" in goals.numbers["top1_accuracy_detected"].definition
    # every effect twin records the gap drawn for it and the gap it has (the drawn one unless
    # the prior top caps it); the report lists every twin
    eff = [t for t in r.twins if t["type"] == "effect"]
    assert all(5.0 <= t["requested_gap_sigma"] <= 10.0 for t in eff)
    assert all(t["twin_gap_sigma"] <= t["requested_gap_sigma"] * (1 + 1e-6) for t in eff)
    # less the fingerprint's own estimation noise, each twin's gap is estimated lower
    assert all(0 <= t["twin_gap_debiased_sigma"] < t["twin_gap_sigma"] for t in eff)
    uncapped = [t for t in eff if t not in capped_twins(r.twins)]
    assert uncapped and all(t["twin_gap_sigma"] == pytest.approx(t["requested_gap_sigma"], rel=1e-6)
                            for t in uncapped)
    table = [s for s in validation_report(r).sections if s.key == "twins"][0].tables[0]
    assert len(table.rows) == len(r.twins) and "twin gap (σ)" in table.columns
    weak = replace(r, twins=[dict(eff[0], twin_gap_sigma=2.5)] + r.twins[1:])
    goals = [s for s in validation_report(weak).sections if s.key == "goals"][0]
    assert f"{eff[0]['true_effect']} (1 twin, 2.5σ)" in goals.text


def test_cli_diagnose_and_validate(tmp_path, capsys, monkeypatch):
    assert main(["diagnose", "--sim", "surrogate", "--real", str(SEED), "--out", str(tmp_path / "d"),
                 "--json"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    j = json.loads(last)
    assert j["simulator"] == "surrogate" and j["verdict"] == "attributed"
    assert j["effect"] == "missing_fines" and len(j["where"]) == 3
    assert j["magnitude"]["interval"][0] <= j["magnitude"]["value"] <= j["magnitude"]["interval"][1]
    assert set(j["shrink"]) >= {"value", "interval"}
    assert (tmp_path / "d" / "report.html").is_file() and (tmp_path / "d" / "diagnosis.json").is_file()
    assert main(["diagnose", "--sim", "surrogate", "--real", str(SEED)]) == 2     # usage
    assert "missing --out" in capsys.readouterr().err
    # an option of the other mode is a usage error, not silently ignored
    assert main(["diagnose", "--sim", "surrogate", "--real", str(SEED), "--out", str(tmp_path / "e"),
                 "--simulator", "engine", "--shard", "0/2"]) == 2
    err = capsys.readouterr().err
    assert "--simulator, --shard apply to 'bedstruct diagnose validate' only" in err
    assert not (tmp_path / "e").exists()
    assert main(["diagnose", "--sim", "surrogate", "--real", str(SEED), "--out", str(tmp_path / "e"),
                 "--score", str(tmp_path)]) == 2
    assert "--score applies to 'bedstruct diagnose benchmark' only" in capsys.readouterr().err
    assert not (tmp_path / "e").exists()
    assert main(["diagnose", "validate", "--real", str(SEED)]) == 2
    assert "--real is for a diagnosis" in capsys.readouterr().err
    assert main(["diagnose", "--sim", "surrogate", "--real", str(tmp_path / "none.toml"),
                 "--out", str(tmp_path)]) == 1
    from bedstruct.diagnose import PRESETS
    monkeypatch.setitem(PRESETS, "tiny", dict(per_effect=1, null=1, out_of_catalogue=0, replicates=2))
    assert main(["diagnose", "validate", "--preset", "tiny", "--json", "--out", str(tmp_path / "v")]) == 0
    j = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    for k in ("top1_accuracy", "null_false_attribution", "out_of_catalogue_unexplained",
              "median_gap_shrink"):
        assert k in j
    assert j["simulator"] == "surrogate"
    assert (tmp_path / "v" / "report.html").is_file()
    assert j["settings"]["refine"] == 2      # the surrogate's default
    # --refine sets each diagnosis's refinement rounds, in either mode, and is recorded
    assert main(["diagnose", "validate", "--preset", "tiny", "--refine", "0", "--json"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["settings"]["refine"] == 0
    assert main(["diagnose", "--sim", "surrogate", "--real", str(SEED), "--out", str(tmp_path / "r"),
                 "--refine", "0", "--json"]) == 0
    capsys.readouterr()
    j = json.loads((tmp_path / "r" / "diagnosis.json").read_text())
    assert j["sim_config"]["refine"] == 0 and j["settings"]["refine"] == 0
    with pytest.raises(SystemExit) as exc:
        main(["diagnose", "validate", "--refine", "-1"])
    assert exc.value.code == 2 and "whole number >= 0" in capsys.readouterr().err
    # --top-up overrides the config's (diagnosis) or the preset's (validation) seeds for
    # marginal effects, and is recorded
    assert main(["diagnose", "--sim", "surrogate", "--real", str(SEED), "--out", str(tmp_path / "t"),
                 "--refine", "0", "--top-up", "3", "--json"]) == 0
    capsys.readouterr()
    assert json.loads((tmp_path / "t" / "diagnosis.json").read_text())["sim_config"]["top_up"] == 3
    with pytest.raises(SystemExit) as exc:
        main(["diagnose", "validate", "--top-up", "x"])
    assert exc.value.code == 2 and "whole number >= 0" in capsys.readouterr().err


def test_cli_help(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["diagnose", "--help"])
    assert exc.value.code == 0
    assert "--sim CONFIG" in capsys.readouterr().out


def test_plots_return_axes():
    import matplotlib
    matplotlib.use("Agg")
    from bedstruct.diagnose import figures as pdg
    ms = load_measurements(SEED)
    sim = SurrogateSimulator(diagnosis_design(ms, catalogue()))
    d = diagnose(ms, sim, base=BASE_PARAMETERS, replicates=2, refine=0)
    for fn, obj in ((pdg.plot_where, d.where), (pdg.plot_fingerprints, d.fingerprints),
                    (pdg.plot_attribution, d.attribution), (pdg.plot_shrink, d.shrink)):
        fig, ax = fn(obj)
        assert ax.figure is fig
        from matplotlib.figure import Figure
        ax2 = fn(obj, ax=Figure().add_subplot(111))
        assert ax2 is not None


@pytest.mark.slow
def test_small_validation_meets_the_goals():
    r = validate("small")
    assert all(g["met"] for g in r.goals.values()), r.goals


def test_observable_order_in_the_file_does_not_matter(twin_setup, tmp_path):
    from dataclasses import replace
    eff, sim, fps = twin_setup
    a = _magnitude_for_snr(fps, "non_sphericity", 8.0)
    real = _twin(sim, fps, tmp_path, {"non_sphericity": a}, 41)
    shuffled = replace(real, measurements=real.measurements[::-1])
    d1 = diagnose(real, sim, base=BASE_PARAMETERS, fingerprints=fps)
    d2 = diagnose(shuffled, sim, base=BASE_PARAMETERS, fingerprints=fps)
    assert d1.where.chi2 == pytest.approx(d2.where.chi2)
    assert d1.where.ranked(1) == d2.where.ranked(1)
    assert d2.attribution.selected[0].effect == "non_sphericity"


def test_the_median_shrink_is_taken_over_twins_with_a_held_out_gap():
    """A twin whose held-out observables show no gap beyond noise has no shrink to score."""
    from bedstruct.diagnose.validation.scores import score_twins

    def twin(shrink, p):
        t = {"type": "effect", "true_effect": "a", "true_magnitude": 0.5, "predicted": "none",
             "verdict": "none", "gap_significant": True, "shrink": shrink, "shrink_rms": shrink}
        return t if p is None else dict(t, p_gap_heldout_before=p)

    # a noise-level gap 'closed' by recalibration alone would lift the median to 1
    s = score_twins([twin(1.0, 0.6), twin(0.2, 1e-4), twin(0.4, 0.01)], ["a"], removed_rows=False)
    assert s["median_gap_shrink"] == pytest.approx(0.3)
    g = s["goals"]["median_gap_shrink"]
    assert (g["n_twins"], g["n_no_heldout_gap"], g["met"]) == (2, 1, False)
    # records written before the test carry no p-value and are kept
    s = score_twins([twin(1.0, None), twin(0.2, 1e-4), twin(0.4, 0.01)], ["a"], removed_rows=False)
    assert s["median_gap_shrink"] == pytest.approx(0.4)
    assert s["goals"]["median_gap_shrink"]["n_no_heldout_gap"] == 0


@pytest.mark.slow  # resuming in workers: test_a_twin_cut_short_resumes_in_its_worker_and_is_merged_once
def test_validation_shards_and_resumes_from_its_records(tmp_path, monkeypatch, capsys, caplog):
    """Shards run disjoint twins of one plan; their merged records score as the whole run."""
    from bedstruct.diagnose import PRESETS
    import importlib

    from bedstruct.errors import ConfigError
    vmod = importlib.import_module("bedstruct.diagnose.validation.validate")
    monkeypatch.setitem(PRESETS, "tiny", dict(per_effect=1, null=2, out_of_catalogue=0, replicates=2))
    whole = validate("tiny", refine=0)
    recs = tmp_path / "twins.jsonl"
    capsys.readouterr()
    parts = [validate("tiny", refine=0, shard=(k, 2), records=recs, progress=k == 1)
             for k in (0, 1)]
    # the bar names the twin it is working on, and only the shard's own twins
    bar = capsys.readouterr().err
    assert "twin 1 (" in bar and "twin 0 (" not in bar
    assert sorted(t["twin"] for p in parts for t in p.twins) == sorted(t["twin"] for t in whole.twins)
    assert not {t["twin"] for t in parts[0].twins} & {t["twin"] for t in parts[1].twins}
    calls = []
    real_diagnose = vmod.diagnose
    monkeypatch.setattr(vmod, "diagnose", lambda *a, **k: calls.append(1) or real_diagnose(*a, **k))
    merged = validate("tiny", refine=0, records=recs)
    assert calls == [] and merged.settings["resumed_twins"] == len(whole.twins)
    key = lambda t: t["twin"]  # noqa: E731
    for a, b in zip(sorted(merged.twins, key=key), sorted(whole.twins, key=key)):
        assert (a["predicted"], a["true_effect"]) == (b["predicted"], b["true_effect"])
    assert merged.top1_accuracy == whole.top1_accuracy
    # each record says where its final rerun departed most, as its diagnosis does
    rows = [json.loads(x) for x in recs.read_text().splitlines()]
    assert all(len(r["rerun_worst"]) > 0 and {w[2] for w in r["rerun_worst"]} <= {"calibrate", "validate"}
               for r in rows)
    # one shard's records scored alone: its twins only, none run, the others listed as not run
    half = tmp_path / "half.jsonl"
    mine = {t["twin"] for t in parts[0].twins}
    half.write_text("".join(x + "\n" for x in recs.read_text().splitlines()
                            if json.loads(x)["twin"] in mine))
    # records state their fingerprints' identifiability: scored without fingerprints
    real_fps = vmod.compute_fingerprints
    fp_calls = []
    monkeypatch.setattr(vmod, "compute_fingerprints",
                        lambda *a, **k: fp_calls.append(1) or real_fps(*a, **k))
    scored = validate("tiny", refine=0, records=half, records_only=True)
    assert fp_calls == [] and scored.settings["scored_from_records"]
    same = lambda a, b: json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)  # noqa: E731
    assert scored.identifiable["effects"] and same(scored.identifiable, parts[0].identifiable)
    assert calls == [] and sorted(map(key, scored.twins)) == sorted(mine)
    # a record written before they did sends the scoring back to the fingerprints
    old = tmp_path / "old.jsonl"
    old.write_text("".join(json.dumps({k: v for k, v in json.loads(x).items()
                                       if k != "fingerprint_identifiable"}) + "\n"
                           for x in half.read_text().splitlines()))
    assert same(validate("tiny", refine=0, records=old, records_only=True).identifiable,
                scored.identifiable) and fp_calls == [1]
    assert sorted(t["twin"] for t in scored.settings["not_run"]) == \
        sorted(t["twin"] for t in parts[1].twins)
    assert scored.top1_accuracy == parts[0].top1_accuracy
    # records of another method version are another validation's: not resumed, their twins
    # not run
    older = tmp_path / "older.jsonl"
    older.write_text("".join(json.dumps(dict(json.loads(x), method_version=0)) + "\n"
                             for x in half.read_text().splitlines()))
    stale = validate("tiny", refine=0, records=older, records_only=True)
    assert stale.twins == [] and len(stale.settings["not_run"]) == len(mine) + len(parts[1].twins)
    # fingerprints topped up otherwise make other twins: those records are not resumed
    other = validate("tiny", refine=0, records=recs, records_only=True, top_up=2)
    assert other.twins == [] and len(other.settings["not_run"]) == len(whole.twins)

    class Stop(Exception):
        pass

    def fingerprints_asked(*a, **k):
        raise Stop(k["top_up"])

    monkeypatch.setattr(vmod, "compute_fingerprints", fingerprints_asked)
    with pytest.raises(Stop, match="^2$"):
        validate("tiny", refine=0, top_up=2)
    monkeypatch.setattr(vmod, "compute_fingerprints", real_fps)
    with pytest.raises(ConfigError, match="top_up"):
        validate("tiny", top_up=-1)
    cli = ["diagnose", "validate", "--preset", "tiny", "--records", str(tmp_path / "cli.jsonl")]
    assert main(cli + ["--shard", "1/2"]) == 0
    capsys.readouterr()
    calls.clear()
    assert main(cli + ["--records-only"]) == 0 and calls == []
    assert f"twins: {len(parts[1].twins)}, not run: {len(parts[0].twins)})" in capsys.readouterr().out
    with pytest.raises(ConfigError, match="records_only"):
        validate("tiny", records_only=True)
    # a recorded effect twin without a significant gap is scored apart in the text output
    lines = [json.loads(x) for x in (tmp_path / "cli.jsonl").read_text().splitlines()]
    first = next(i for i, t in enumerate(lines) if t["type"] == "effect")
    lines[first]["gap_significant"] = False
    weak = tmp_path / "weak.jsonl"
    weak.write_text("".join(json.dumps(t) + "\n" for t in lines))
    capsys.readouterr()
    assert main(["diagnose", "validate", "--preset", "tiny", "--records", str(weak),
                 "--records-only"]) == 0 and calls == []
    out = capsys.readouterr().out
    assert "twins with a significant gap only (1 effect twin(s) without)" in out, out
    # another validation's records are not taken as done
    other = validate("tiny", refine=0, records=recs, twin_seed=7)
    assert other.settings["resumed_twins"] == 0 and len(calls) == len(whole.twins)
    # ... nor those of other statistics settings, nor twins made by another method version
    assert validate("tiny", refine=0, records=recs, alpha=0.01).settings["resumed_twins"] == 0
    lines = recs.read_text().splitlines()
    recs.write_text("".join(json.dumps(dict(json.loads(x), method_version=0)) + "\n"
                            for x in lines))
    with caplog.at_level("WARNING", logger="bedstruct.diagnose.validation"):
        assert validate("tiny", refine=0, records=recs).settings["resumed_twins"] == 0
    # the user is told why nothing was resumed
    assert f"method_version 0 (this run: {vmod.METHOD_VERSION})" in caplog.text
    recs.write_text("{not json\n")
    with pytest.raises(ConfigError, match="line 1"):
        validate("tiny", refine=0, records=recs)
    recs.write_text('{"twin": 0, "type": "nul"}\n')
    with pytest.raises(ConfigError, match="line 1: not a twin record"):
        validate("tiny", refine=0, records=recs)
    with pytest.raises(ConfigError, match="shard"):
        validate("tiny", shard=(2, 2))
    with pytest.raises(SystemExit):
        main(["diagnose", "validate", "--shard", "3"])
    assert "K/N" in capsys.readouterr().err


def test_engine_twin_plan_takes_the_effects_in_turn():
    from bedstruct.diagnose.validation.twins import _twin_plan
    cfg = dict(per_effect=2, null=2, out_of_catalogue=0)
    plan = _twin_plan(["a", "b", "c"], cfg, in_turn=True)
    assert plan == [("null", None)] * 2 + [("effect", e) for e in "abcabc"]
    # any half of it (a shard) still covers every effect
    assert {e for _, e in plan[2::2]} == {e for _, e in plan[3::2]} == set("abc")
    assert _twin_plan(["a", "b"], cfg, in_turn=False)[:4] == [("effect", "a")] * 2 + [("effect", "b")] * 2


def test_a_twins_repeated_experiments_are_handed_to_a_parallel_simulator_at_once(twin_setup,
                                                                                 tmp_path):
    # on the engine with jobs > 1 the repeats run side by side (three calls of ~4 min each
    # at small), not one after another; the file is the same either way
    from bedstruct.diagnose.validation.twins import _repeat_seed
    eff, sim, fps = twin_setup
    batches = []

    class Parallel:
        def prefetch(self, calls):
            batches.append(list(calls))

        def __call__(self, base, effects, seed):
            return sim(base, effects, seed)

    design = twin_design()
    args = (dict(BASE_PARAMETERS), {"blade_startup": 0.1}, 11, tmp_path, 11, sim.noise_sd(), 3)
    with_prefetch = _twin_measurements(design, Parallel(), *args)
    assert batches == [[(dict(BASE_PARAMETERS), {"blade_startup": 0.1}, _repeat_seed(11, k))
                        for k in range(3)]]
    plain = _twin_measurements(design, sim, *args)
    for m in design:
        assert np.array_equal(with_prefetch[m.name].values, plain[m.name].values)


def test_twins_run_in_processes_make_the_serial_records(tiny_serial, tmp_path):
    """``twin_jobs``: the twins left to run go to worker processes, one twin each; their
    records are those a serial run makes, and are merged into ``records``."""
    serial, lines, _ = tiny_serial
    left = {json.loads(x)["twin"] for x in lines[-2:]}
    part = tmp_path / "part.jsonl"
    part.write_text("".join(x + "\n" for x in lines if json.loads(x)["twin"] not in left))
    par = validate("tiny", refine=0, records=part, twin_jobs=2)
    assert par.settings["twins_run_in_processes"] == len(left)
    assert par.settings["resumed_twins"] == len(lines) - sum(
        json.loads(x)["twin"] in left for x in lines)
    key = lambda t: (t["twin"], t["type"])  # noqa: E731
    # every twin of the parallel run is scored from its record: compare records with records
    assert json.dumps(sorted(par.twins, key=key), sort_keys=True) == \
        json.dumps(sorted(map(json.loads, lines), key=key), sort_keys=True)
    assert sorted(json.loads(x)["twin"] for x in part.read_text().splitlines()) == \
        sorted(json.loads(x)["twin"] for x in lines)
    assert par.top1_accuracy == serial.top1_accuracy
    from bedstruct.errors import ConfigError
    with pytest.raises(ConfigError, match="twin_jobs"):
        validate("tiny", twin_jobs=2, shard=(0, 2))
    with pytest.raises(ConfigError, match="cache"):
        validate("mini", simulator="engine", twin_jobs=2)
    with pytest.raises(ConfigError, match="whole number"):
        validate("tiny", twin_jobs=0)


def test_a_twin_cut_short_resumes_in_its_worker_and_is_merged_once(tiny_serial, tmp_path):
    """A worker's records file starts with what ``records`` holds of its twin, so a twin
    interrupted between its diagnoses is not diagnosed again, and merging writes each line
    once (before, a resumed twin's finished record was redone and then stood twice)."""
    from bedstruct.diagnose.validation.parallel import run_twins_in_processes
    lines = tiny_serial[1]
    first = json.loads(lines[0])["twin"]
    other = json.loads(lines[-1])["twin"]
    # the finished record carries a mark a rerun would not write: had the worker diagnosed
    # the twin again, an unmarked record of it would stand beside the marked one
    given = json.dumps({**json.loads(lines[0]), "given": True})
    records = tmp_path / "records.jsonl"
    records.write_text(given + "\n")
    n_twins = len({json.loads(x)["twin"] for x in lines})
    run_twins_in_processes(validate, dict(preset="tiny", refine=0), [first, other], n_twins, records, 2)
    got = records.read_text().splitlines()
    assert got.count(given) == 1
    assert [json.loads(x)["twin"] for x in got].count(first) == 1
    assert json.loads(got[-1]) == json.loads(lines[-1])
    assert not list(tmp_path.glob("bedstruct-twin-records-*"))


def test_a_status_line_that_cannot_be_written_does_not_stop_the_twin(tmp_path, monkeypatch):
    """The status line is a courtesy: a disk error writing it leaves the twin's records."""
    from bedstruct.diagnose.validation import parallel as validate_parallel

    def refuse(*args):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(validate_parallel.os, "replace", refuse)
    part = str(tmp_path / "twin0.jsonl")
    # a shard count above the plan's length: twin 0 alone
    validate_parallel._one_twin(validate, dict(preset="tiny", refine=0), 0, 1000, part)
    assert [json.loads(x)["twin"] for x in pathlib.Path(part).read_text().splitlines()] == [0]
    assert validate_parallel._read_status(part) == ""


def test_running_twins_say_how_far_they_have_come(tiny_serial, tmp_path):
    """``on_status`` hears which twin runs (its worker process writes that line beside its
    records, where the bar of ``twin_jobs`` reads it); merging the records removes it."""
    from bedstruct.diagnose.validation.parallel import _append, _one_twin, _read_status
    res, _, statuses = tiny_serial
    names = {t["twin"]: t["true_effect"] or "null" for t in res.twins}
    assert statuses == [f"twin {i} ({names[i]})" for i in sorted(names)]
    part = str(tmp_path / "twin3.jsonl")
    assert _read_status(part) == ""
    _one_twin(validate, dict(preset="tiny", refine=0), 3, len(names), part)
    assert _read_status(part) == f"twin 3 ({names[3]})"
    merged = tmp_path / "records.jsonl"
    _append(pathlib.Path(part), merged)
    assert {json.loads(x)["twin"] for x in merged.read_text().splitlines()} == {3}
    assert not list(tmp_path.glob("twin3*"))
