"""HTML/JSON report of a diagnosis (built on ``bedstruct.report``).

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
import re

from .._version import __version__
from .answer import (_MAGNITUDE_WORDS, _PARAMETER_WORDS, _component_words, _num, _observable_words,
                     _unit_of, answer, conditions_text, difference_text, quantity_text)
from .diagnosis_result import identification, uneven_scatter_note
from .separation import nearest_imitations

__all__ = ["diagnosis_report"]


_ROLE_WORDS = {"calibrate": "calibration", "validate": "held out", "candidate": "not measured"}


def _fmt(v, nd=3):
    if isinstance(v, float):
        return float(f"{v:.{nd}g}") if v == v else None
    return v


#: A value below this fraction of its scale is rounding noise (shown and recorded as 0).
_NOISE = 1e-12


def _noise_free(v, scale):
    """``v``, or 0.0 where it is rounding noise against ``scale`` (e.g. an effect's prior)."""
    if isinstance(v, float) and math.isfinite(v) and abs(v) < _NOISE * abs(scale):
        return 0.0
    return v


def _prior_scale(effect) -> float:
    """The size of an effect's magnitude: the largest end of its prior."""
    return max((abs(float(b)) for b in effect.prior), default=1.0) or 1.0


def _magnitude_unit(effect) -> tuple[float, str]:
    """The factor and natural unit an effect's magnitude is shown in (%, ms, ...)."""
    _, f, u, _ = _MAGNITUDE_WORDS.get(effect.magnitude, (None, 1.0, effect.unit, False))
    return f, (u or "1")


def _window_words(text: str) -> str:
    """``text`` with each time window ``t=t0-t1`` (fractions of the stroke) said in % of the stroke."""
    return re.sub(r"(?<!\w)t=[0-9.eE+-]+-[0-9.eE+-]+(?![\w.%])",
                  lambda m: _component_words(m.group(0)), text)


def _shift_words(name: str, value: float) -> str:
    """A recalibration shift of parameter ``name`` in its natural unit (``+2 MJ/m³``)."""
    _, f, u = _PARAMETER_WORDS.get(name, (name, 1.0, ""))
    return f"{name} {_num(value * f, signed=True)}{(' ' + u) if u else ''}"


def _add(section, key, value, unit, definition) -> None:
    """A number in a section, unless it is not a number (NaN, infinite: said in words)."""
    if isinstance(value, float) and not math.isfinite(value):
        return
    section.add_number(key, _fmt(value), unit, definition)


def _identified_by(fps, row) -> str:
    if row["identifiable"] or row["identify_with"]:
        return ", ".join(row["identify_with"])
    return identification(fps, row["effect"])["note"]


def diagnosis_report(diag, *, title: str | None = None, amortised=None):
    """A :class:`bedstruct.report._model.Report` of a :class:`Diagnosis`.

    The first section is the answer in plain words with the figure of measured against
    simulated values (:func:`~bedstruct.diagnose.figures.plot_gaps`); the statistics follow
    in appendices. With ``amortised`` (an
    :class:`~bedstruct.diagnose.amortised.AmortisedDiagnosis` whose diagnosis is ``diag``),
    an appendix compares the emulator's prediction with the simulator's confirming rerun.
    """
    from ..report._model import Report, Table, run_section, skip
    from . import figures as pdg

    j = diag.to_json()
    sim_note = ("Simulations by the analytic SURROGATE (bedstruct.diagnose.surrogate), not the DEM "
                "engine: numbers show what the method does, not what the powder does."
                if diag.simulator == "surrogate" else f"Simulations by: {diag.simulator}.")
    rep = Report(title or f"Sim-to-real gap diagnosis: {diag.measurements.title}",
                 inputs={"measurements": diag.measurements.path or diag.measurements.title,
                         "simulator": diag.simulator},
                 settings=diag.settings, version=__version__)

    def summary(s):
        verdict = j["verdict"] + (" (partial)" if j["partial"] else "")
        s.text = f"{sim_note} Verdict: {verdict}. {j['reason']}."
        _add(s, "verdict", verdict, "", "attributed / unexplained / none (no gap to explain); "
             "partial: the effect closes most of the held-out gap but not all of it")
        _add(s, "gap_significant", j["gap_significant"], "",
                     "whether the chi-square or max-|z| test rejects 'no gap' (all measured observables)")
        _add(s, "gap_chi2", j["gap_chi2"]["chi2"], "1", "sum of squared standardised residuals")
        _add(s, "gap_dof", j["gap_chi2"]["dof"], "1", "number of measured components")
        _add(s, "confidence", j["confidence"], "1",
                     "BIC weight of models containing the top effect (or of the null model)")
        if isinstance(j["which"], list):
            for e in j["which"]:
                eff = diag.fingerprints[e["effect"]].effect
                f, u = _magnitude_unit(eff)
                ref = _prior_scale(eff) * f
                lo, hi = (_noise_free(v * f, ref) for v in e["interval"])
                _add(s, f"magnitude.{e['effect']}", _noise_free(e["magnitude"] * f, ref), u,
                     f"fitted {eff.magnitude}, 95 % CI [{_num(lo)}, {_num(hi)}]")
        _add(s, "shrink", j["shrink"]["fraction"], "1",
                     "1 - excess held-out gap after / before (NaN when there was no held-out gap)")
        if j["next"]:
            _add(s, "next_measurement", j["next"][0]["observable"], "",
                         f"separates {' vs '.join(j['next'][0]['separates'])} by "
                         f"{j['next'][0]['separation_sigma']:.1f} sigma")

    def where_(s):
        w = diag.where
        s.text = _window_words(" | ".join(w.summary[:6]))
        rows = []
        for r in w.ranked():
            f, u = _unit_of(r["real"], r["unit"], r["kind"])
            rows.append([r["observable"], _component_words(r["component"]), r["role"],
                         conditions_text(r["conditions"]), _fmt(r["real"] * f, 4), _fmt(r["simulated"] * f, 4),
                         _fmt(r["sigma"] * f), u, _fmt(r["z"])])
        s.tables.append(Table(["observable", "component", "role", "conditions", "real", "simulated",
                               "sigma", "unit", "z"], rows,
                              caption="standardised residuals, largest |z| first; real, "
                                      "simulated and sigma in the unit of the row"))
        s.tables.append(Table(["group", "key", "n", "chi2", "rms z", "max z", "p"],
                              [[g.group, _window_words(g.key), g.n, _fmt(g.chi2), _fmt(g.rms_z),
                                _fmt(g.max_z), _fmt(g.p_value)] for g in w.groups],
                              caption="aggregates by observable, by kind and time window, by role"))
        fig, _ = pdg.plot_where(w)
        s.add_figure(fig, "largest standardised residuals")

    def fingerprints_(s):
        fps = diag.fingerprints
        s.text = ("Change of every observable per effect at the top of its prior, whitened by the "
                  "combined noise; identifiability judged on calibration observables after "
                  "projecting out what recalibrating " + ", ".join(fps.nuisance) + " absorbs.")
        s.tables.append(Table(["effect", "signal (sigma)", "its standard error", "noise (sigma)",
                               "identifiable", "seeds", "signal on one run", "confounded with",
                               "would be identified by"],
                              [[r["effect"], _fmt(r["signal_sigma"]), _fmt(r["signal_se_sigma"]),
                                _fmt(r["noise_sigma"]), r["identifiable"], r["seeds"],
                                _fmt(r["single_run_share"]), ", ".join(r["confounded_with"]),
                                _identified_by(fps, r)] for r in fps.table()]))
        if fps.topped_up:
            s.text += (f" {', '.join(fps.topped_up)}: identifiability marginal on the "
                       f"{fps.n_replicates} shared seeds, so run again with the base on "
                       f"{len(fps.top_up_seeds)} more.")
        thin = [f.name for f in fps.fingerprints
                if f.single_run_share > 0.5 and f.name not in fps.topped_up]
        if thin:
            s.text += (f" {', '.join(thin)}: more than half the signal lies on observables that "
                       "the prior top observed in one run only (the other runs could not observe "
                       "them), so its size rests on that run; more replicate seeds would judge it.")
        s.tables.append(Table(["effect", "closest imitation by", "unique part", "told apart from a gap of (sigma)",
                               "signal at prior top (sigma)"],
                              [[r["effect"], r["other"], _fmt(r["unique_fraction"]),
                                _fmt(r["gap_to_separate_sigma"]), _fmt(r["signal_sigma"])]
                               for r in nearest_imitations(fps)],
                              caption="which effects the calibration observables tell apart: the part of each "
                                      "effect's fingerprint (at its prior top) that the closest other effect "
                                      "cannot imitate, and the gap from which on the two are told apart"))
        notes = diag.data_notes()
        if notes:
            if diag.settings.get("missing_runs"):
                s.text += (" Runs that could not observe an observable (NaN) count as missing "
                           "data: means and differences use the replicates that did.")
            s.text += " Data notes: " + " ".join(n + "." for n in notes)
        fig, _ = pdg.plot_fingerprints(fps)
        s.add_figure(fig, "fingerprints")

    def which_(s):
        att = diag.attribution
        s.text = att.reason
        chi2_scale = max((abs(m.chi2) for m in att.models if math.isfinite(m.chi2)), default=1.0)
        rows = []
        for e in att.ranking:
            eff = diag.fingerprints[e.effect].effect
            f, u = _magnitude_unit(eff)
            ref = _prior_scale(eff) * f
            lo, hi = (_noise_free(v * f, ref) for v in e.interval)
            rows.append([e.effect, _fmt(_noise_free(e.magnitude * f, ref)),
                         f"[{_num(lo)}, {_num(hi)}]", u,
                         _fmt(_noise_free(e.scale, 1.0)), _fmt(_noise_free(e.delta_chi2, chi2_scale)),
                         _fmt(e.p_value), _fmt(e.confidence), e.identifiable])
        s.tables.append(Table(["effect", "magnitude", "95 % CI", "unit", "scale", "dchi2", "p",
                               "confidence", "identifiable"], rows,
                              caption="each effect fitted alone (with recalibration), ranked by "
                                      "chi-square drop; the chosen model's intervals are from the "
                                      "profile of chi-square, the others' the normal approximation"))
        s.tables.append(Table(["model", "chi2", "dof", "p (fit)", "AIC", "BIC", "BIC weight"],
                              [[m.label, _fmt(m.chi2), m.dof, _fmt(m.p_value), _fmt(m.aic), _fmt(m.bic),
                                _fmt(m.weight)] for m in att.models[:12]],
                              caption="model comparison (calibration observables only)"))
        fig, _ = pdg.plot_attribution(att)
        s.add_figure(fig, "fitted scale factors")
        if att.selected or att.ranking:
            fig, _ = pdg.plot_effect_response(diag)
            s.add_figure(fig, "the leading effect's interpolated response against its magnitude, "
                              "through its simulated nodes, and what the data ask of it (dotted)")
            fig, _ = pdg.plot_magnitude_profile(diag)
            s.add_figure(fig, "the profile of chi-square over the leading effect's magnitude: "
                              "the band is its 95 % interval")

    def shrink_(s):
        sh = diag.shrink
        if sh.n_heldout == 0:
            skip("no held-out (validate) observables")
        shifts = ", ".join(_shift_words(k, v) for k, v in sh.nuisance.items()) or "none"
        s.text = (f"Rerun of {sh.model} at the magnitude fitted on calibration observables only "
                  f"(recalibration shifts: {shifts}); gaps on held-out observables, in units "
                  "of the noise.")
        for k in ("before", "recalibrated", "after"):
            _add(s, f"gap_{k}", getattr(sh, k), "1", f"RMS z on held-out components, {k}")
        _add(s, "excess_before", sh.before_excess, "1", "sqrt(max(mean z^2 - 1, 0)), before")
        _add(s, "excess_after", sh.after_excess, "1", "same, after")
        _add(s, "shrink", sh.fraction, "1", "1 - excess after / excess before")
        lo, hi = sh.fraction_interval
        if math.isfinite(lo) and math.isfinite(hi):
            _add(s, "shrink_interval", f"{lo:.2f} to {hi:.2f}", "1",
                 "90 % interval of the shrink (parametric bootstrap of the held-out residuals)")
        _add(s, "shrink_rms", sh.fraction_rms, "1", "1 - RMS after / RMS before")
        if math.isfinite(sh.p_before):
            _add(s, "p_heldout_gap_before", sh.p_before, "1",
                         "chi-square test of the held-out gap before against noise (a shrink "
                         "of a gap within noise measures noise)")
        if math.isfinite(sh.p_rerun_calibration):
            _add(s, "p_rerun_calibration", sh.p_rerun_calibration, "1",
                         "fit of the rerun to the calibration observables (confirms the attribution)")
        if math.isfinite(sh.p_rerun_heldout):
            _add(s, "p_rerun_heldout", sh.p_rerun_heldout, "1",
                         "fit of the rerun to the held-out observables, within the fit's uncertainty")
        if math.isfinite(sh.p_rerun_trials):
            _add(s, "p_rerun_trials", sh.p_rerun_trials, "1",
                         "the file's trials without a reading against the model's runs "
                         "(Fisher exact per observable, Sidak; 1: nothing to test)")
        if sh.trial_rows:
            s.tables.append(Table(
                ["observable", "trials without a reading", "model's runs without one", "p"],
                [[r["observable"], f"{r['unread']} of {r['trials']}",
                  " or ".join(f"{k} of {n}" for k, n in r["pools"]), _fmt(r["p"])]
                 for r in sh.trial_rows],
                caption="trials that gave no reading (a pile that stood as a block, no heap to "
                        "fit) against the final model's runs: its rerun, and its fingerprint "
                        "points below and above its magnitude; the larger p of the two pools"))
        if sh.refits:
            s.tables.append(Table(
                ["rerun model", "magnitudes", "p (fit)", "p (rerun, calibration)",
                 "p (rerun, held-out)", "seeds", "re-simulated"],
                [[r["model"], ", ".join(f"{e} = {a:.3g}" for e, a in r["magnitudes"].items()),
                  _fmt(r["p_fit"]), _fmt(r["p_rerun_calibration"]), _fmt(r["p_rerun_heldout"]),
                  ", ".join(map(str, r["seeds"])),
                  ("base at " + ", ".join(_shift_words(k, v) for k, v in r["recalibration"].items())
                   if "recalibration" in r else "the rerun as a fingerprint node")]
                 for r in sh.refits],
                caption="reruns that contradicted the fit on the calibration observables; what "
                        "was re-simulated before the model was refitted"))
        s.tables.append(Table(["observable", "before", "recalibrated", "after"],
                              [[r["observable"], _fmt(r["before"]), _fmt(r["recalibrated"]),
                                _fmt(r["after"])] for r in sh.per_observable]))
        if sh.rerun_worst:
            s.tables.append(Table(
                ["observable", "component", "role", "z (rerun)"],
                [[w["observable"], _component_words(w["component"]),
                  "calibration" if w["role"] == "calibrate" else "held out", f"{w['z']:+.2f}"]
                 for w in sh.rerun_worst],
                caption="where the final rerun departs most from the data (a failed check "
                        "comes from these components)"))
        fig, _ = pdg.plot_shrink(sh)
        s.add_figure(fig, "held-out gap before and after")

    def next_(s):
        if not diag.next:
            skip("no second candidate model to separate")
        s.text = ("Observables (held-out or not yet measured) ranked by how far the predictions of "
                  "the top two models differ, in units of the noise.")
        s.tables.append(Table(["observable", "kind", "conditions", "status", "separation (sigma)",
                               "separates"],
                              [[n.observable, n.kind, conditions_text(n.conditions),
                                "measured" if n.measured else "not measured", _fmt(n.separation),
                                " vs ".join(n.separates)] for n in diag.next]))

    def catalogue_(s):
        s.tables.append(Table(["effect", "magnitude", "unit", "prior", "physics", "sources"],
                              [[f.effect.name, f.effect.magnitude, f.effect.unit, list(f.effect.prior),
                                f.effect.physics, " | ".join(f.effect.sources)]
                               for f in diag.fingerprints.fingerprints]))

    def answer_(s):
        a = answer(diag)
        s.text = a.headline
        s.tables.append(Table(["question", "answer"],
                              [["Which effect", a.which], ["How far", a.how_far],
                               ["Recalibration", a.recalibration], ["What next", a.next]]))
        gaps = {g["what"]: g for g in a.gaps}
        after = any(math.isfinite(g["after"]) for g in a.gaps)

        def sim_text(r, key):
            g = gaps.get(r["what"])
            if g is None or not math.isfinite(g[key]):
                return "n/a"
            return f"{_num(g[key])} {g['unit']}".strip()

        cols = ["observable", "role", "measured", "simulated", "recalibrated"]
        cols += ["with the effect"] if after else []
        s.tables.append(Table(cols + ["gap"],
                              [[r["what"], r["role"], r["measured"], r["simulated"],
                                sim_text(r, "before")]
                               + ([sim_text(r, "after")] if after else []) + [r["gap"]]
                               for r in a.where],
                              caption="where the simulation misses the measurements, largest "
                                      "gap first (measured ± its uncertainty; simulated: the "
                                      "base model; recalibrated, and with the effect added: "
                                      "the reruns; the gap is the base model's)"))
        fig, _ = pdg.plot_gaps(diag)
        s.add_figure(fig, "measured against simulated for every measured observable: the "
                          "recalibrated model before and after adding the effect, in units of "
                          "the measurement's uncertainty (values in their units on the left)")
        if amortised is not None:
            s.text += " " + amortised.summary_line()

    def emulator_(s):
        c = amortised.check
        s.text = (f"The diagnosis ran on the emulator of a run library ({amortised.library_runs} "
                  f"runs; leave-one-out error {amortised.loo_rmse_sigma:.2f} sigma). Before the "
                  f"simulator was rerun at the answer ({c.n_runs} runs), the emulator predicted "
                  "each observable there; the table compares the prediction with the rerun's "
                  "mean, the standardised error z = (rerun - predicted) / sd.")
        _add(s, "confirm_rmse_sigma", float(c.rmse_sigma), "1",
             "RMS of the standardised errors of the rerun (1 when the emulator is calibrated)")
        _add(s, "confirm_within_2sigma", float(c.within_2sigma), "1",
             "fraction of components within 2 sd of the prediction (0.95 when calibrated)")
        _add(s, "loo_rmse_sigma", float(amortised.loo_rmse_sigma), "1",
             "the emulator's leave-one-point-out error on the library, in sigma")
        rows = amortised.confirm_rows()
        s.tables.append(Table(
            ["observable", "role", "emulator prediction", "simulator rerun",
             "rerun - prediction", "z"],
            [[_observable_words(r), _ROLE_WORDS.get(r["role"], r["role"]),
              quantity_text(r["predicted"], r["unit"], r["kind"], sigma=r["predicted_sd"]),
              quantity_text(r["rerun"], r["unit"], r["kind"]),
              difference_text(r["rerun"] - r["predicted"], r["predicted"], r["unit"], r["kind"]),
              f"{r['z']:+.2f}" if math.isfinite(r["z"]) else "not observed"] for r in rows],
            caption="the emulator's prediction (± its predictive sd for the rerun's mean) "
                    "against the simulator's confirming rerun at the answer"))

    for key, title_, fn in (("answer", "The answer", answer_),
                            ("summary", "Appendix: summary statistics", summary),
                            ("where", "Appendix: where (standardised residuals)", where_),
                            ("fingerprints", "Appendix: fingerprints and identifiability",
                             fingerprints_),
                            ("which", "Appendix: which effect (model comparison)", which_),
                            ("shrink", "Appendix: how far (held-out gaps)", shrink_),
                            ("next", "Appendix: what to measure next", next_),
                            ("catalogue", "Appendix: catalogue of effects", catalogue_),
                            *((("emulator", "Appendix: the emulator against the confirming rerun",
                                emulator_),) if amortised is not None else ())):
        # "ok" beside the verdict would read as a judgement of the simulation
        rep.sections.append(run_section(key, title_, fn, ok_badge=False))
    return rep
