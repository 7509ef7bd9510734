"""Figures of the sim-to-real gap diagnosis (gaps, where, fingerprints, which, shrink, validation).

Every function takes a result object, ``ax=None`` and returns the Axes (or
``(fig, ax)`` when it created the figure); nothing is shown or saved.
"""

from __future__ import annotations

import numpy as np

from .profile_interval import profile_interval

__all__ = ["plot_gaps", "plot_where", "plot_fingerprints", "plot_attribution", "plot_effect_response",
           "plot_magnitude_profile", "plot_shrink", "plot_confusion"]


def _axes(ax, size=(6.4, 4.0)):
    try:
        from matplotlib.figure import Figure
    except ImportError as exc:  # pragma: no cover
        raise ImportError("plotting needs matplotlib: pip install matplotlib") from exc
    if ax is not None:
        return None, ax
    fig = Figure(figsize=size)
    return fig, fig.add_subplot(111)


def _ret(fig, ax):
    return ax if fig is None else (fig, ax)


def _leading_effect(attribution, effect, caller: str) -> str:
    """``effect``, or by default the attributed effect, else the best candidate fitted alone."""
    if effect is not None:
        return effect
    if attribution.selected:
        return attribution.selected[0].effect
    if attribution.ranking:
        return attribution.ranking[0].effect
    raise ValueError(f"{caller}: the diagnosis has no effect to show")


def _after_label(diagnosis) -> str | None:
    """The legend of the rerun with the effect(s) added (None: there was none)."""
    sh = diagnosis.shrink
    if not sh.magnitudes:
        return None
    names = " + ".join(e.replace("_", " ") for e in sh.magnitudes)
    if diagnosis.verdict == "attributed":
        return f"after: recalibrated + {names}"
    return f"recalibrated + {names} (rejected by its rerun)"


def plot_gaps(diagnosis, *, ax=None):
    """Measured against simulated for every measured observable, before and after the effect.

    One row per observable component, largest gap first. The horizontal axis is the
    simulated minus the measured value in units of the measurement's uncertainty, so that
    observables in µm, deg and % share it; each row's label gives the measured value and
    the simulated ones in their natural unit. Black: the measurement, its bar ±1
    uncertainty; grey: the recalibrated base model ("before"); red: the recalibrated model
    with the chosen effect added ("after"), each with a bar of ±1 standard deviation of its
    mean from the run scatter. Orange labels are held-out observables. The numbers are
    those of :func:`~bedstruct.diagnose.answer.gap_rows`.

    Parameters
    ----------
    diagnosis : Diagnosis

    Returns
    -------
    (Figure, Axes), or the Axes when ``ax`` is given

    Examples
    --------
    >>> import pathlib
    >>> import bedstruct.diagnose as dg
    >>> ms = dg.load_measurements(pathlib.Path(dg.__file__).parents[2] / "data/measurements/seed.toml")
    >>> sim = dg.SurrogateSimulator(dg.diagnosis_design(ms, dg.catalogue(["missing_fines"])))
    >>> d = dg.diagnose(ms, sim, base=dg.BASE_PARAMETERS, effects=dg.catalogue(["missing_fines"]),
    ...                 replicates=2, refine=0)
    >>> fig, ax = plot_gaps(d)
    >>> [c.get_label() for c in ax.containers]
    ['measured', 'before: recalibrated', 'after: recalibrated + missing fines']
    """
    from .answer import _num, gap_rows
    rows = gap_rows(diagnosis)
    fig, ax = _axes(ax, (7.2, 0.38 * max(len(rows), 1) + 1.6))
    if not rows:
        ax.text(0.5, 0.5, "no measured observable", ha="center", transform=ax.transAxes)
        return _ret(fig, ax)
    y = np.arange(len(rows))[::-1].astype(float)
    zeros = np.zeros(len(rows))
    ax.errorbar(zeros, y, xerr=np.ones(len(rows)), fmt="s", color="k", ms=4, capsize=2,
                label="measured")
    after = _after_label(diagnosis)
    has_after = after is not None and any(np.isfinite(r["after"]) for r in rows)
    dy = 0.15 if has_after else 0.0
    ax.errorbar([r["gap_before"] for r in rows], y + dy,
                xerr=[r["before_sd"] / r["sigma"] for r in rows], fmt="o", color="0.55", ms=4,
                capsize=2, label="before: recalibrated")
    if has_after:
        ax.errorbar([r["gap_after"] for r in rows], y - dy,
                    xerr=[r["after_sd"] / r["sigma"] for r in rows], fmt="o", color="#c53030",
                    ms=4, capsize=2, label=after)

    def unit(r):
        return f" {r['unit']}" if r["unit"] else ""

    labels = []
    for r in rows:
        sim = _num(r["before"])
        if has_after and np.isfinite(r["after"]):
            sim += f" → {_num(r['after'])}"
        labels.append(f"{r['what']}: measured {_num(r['measured'])} ± {_num(r['sigma'], 2)}"
                      f"{unit(r)}, simulated {sim}{unit(r)}")
    ax.set_yticks(y)
    ax.set_yticklabels(labels, fontsize=7)
    for tick, r in zip(ax.get_yticklabels(), rows):
        if r["role"] == "held out":
            tick.set_color("#dd6b20")
    for v in (-2, 2):
        ax.axvline(v, color="0.7", ls="--", lw=0.8)
    ax.axvline(0, color="k", lw=0.6)
    ax.set_xlabel("simulated − measured, in units of the measurement's uncertainty")
    head = {"attributed": "gap before and after adding the effect",
            "none": "no effect added: recalibration alone closes the gap",
            "unexplained": "unexplained: no effect of the catalogue closes the gap"}
    ax.set_title(f"Measured against simulated ({head.get(diagnosis.verdict, diagnosis.verdict)}); "
                 "orange: held out", fontsize=8)
    ax.legend(fontsize=7, loc="best")
    return _ret(fig, ax)


def plot_where(result, *, ax=None, n=15):
    """Horizontal bars of the largest standardised residuals (``WhereResult``).

    Bars are coloured by role (calibrate/validate); dashed lines mark +-2 sigma.

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct.diagnose import measurement_from_dict, MeasurementSet, where
    >>> m = measurement_from_dict({"name": "a", "kind": "static_angle", "value": 33.0,
    ...                            "uncertainty": 0.5})
    >>> res = where(MeasurementSet((m,)), np.array([[30.0], [30.2]]))
    >>> fig, ax = plot_where(res)
    >>> len(ax.patches)
    1
    """
    fig, ax = _axes(ax, (6.4, 0.35 * min(n, len(result.order)) + 1.2))
    rows = result.ranked(n)[::-1]
    z = [r["z"] for r in rows]
    labels = [f"{r['observable']} [{r['component']}]" for r in rows]
    colors = ["#2b6cb0" if r["role"] == "calibrate" else "#dd6b20" for r in rows]
    ax.barh(np.arange(len(z)), z, color=colors)
    ax.set_yticks(np.arange(len(z)))
    ax.set_yticklabels(labels, fontsize=7)
    for v in (-2, 2):
        ax.axvline(v, color="0.5", ls="--", lw=0.8)
    ax.axvline(0, color="k", lw=0.8)
    ax.set_xlabel("standardised residual z (real - sim) / sigma")
    ax.set_title("where: blue = calibrate, orange = held out", fontsize=9)
    return _ret(fig, ax)


def plot_fingerprints(fps, *, ax=None):
    """Heat map of each effect's whitened change at the prior top, per design component."""
    fig, ax = _axes(ax, (8.0, 0.45 * len(fps.fingerprints) + 2.2))
    if not fps.fingerprints:
        ax.text(0.5, 0.5, "no effects", ha="center", transform=ax.transAxes)
        return _ret(fig, ax)
    M = np.array([f.delta[1] / fps.sigma for f in fps.fingerprints])
    lim = max(float(np.nanmax(np.abs(M))), 1e-9)
    im = ax.imshow(M, aspect="auto", cmap="RdBu_r", vmin=-lim, vmax=lim)
    ax.set_yticks(range(len(fps.fingerprints)))
    ax.set_yticklabels([f.name + ("" if f.identifiable else " (n.i.)") for f in fps.fingerprints],
                       fontsize=7)
    names = fps.design.component_names()
    labels = fps.design.component_labels()
    roles = fps.design.roles()
    ax.set_xticks(range(len(names)))
    ax.set_xticklabels([f"{n}[{l}]{'*' if r == 'candidate' else ''}" for n, l, r in
                        zip(names, labels, roles)], rotation=90, fontsize=6)
    if ax.figure is not None:
        ax.figure.colorbar(im, ax=ax, label="change / sigma at prior top")
    ax.set_title("fingerprints (* = candidate measurement, n.i. = not identifiable)", fontsize=9)
    return _ret(fig, ax)


def plot_attribution(attribution, *, ax=None):
    """Fitted scale factors (magnitude / prior top) with 95 % intervals, per effect."""
    fig, ax = _axes(ax)
    est = list(attribution.ranking)
    y = np.arange(len(est))[::-1]
    for yi, e in zip(y, est):
        sel = any(s.effect == e.effect for s in attribution.selected)
        ax.errorbar(e.scale, yi, xerr=[[e.scale - e.scale_interval[0]], [e.scale_interval[1] - e.scale]],
                    fmt="o", color="#c53030" if sel else "#4a5568", capsize=3)
    ax.set_yticks(y)
    ax.set_yticklabels([f"{e.effect} (dchi2={e.delta_chi2:.1f})" for e in est], fontsize=7)
    ax.axvline(0, color="k", lw=0.8)
    ax.set_xlabel("fitted magnitude / prior top (95 % CI), each effect alone")
    ax.set_title(f"which: {attribution.verdict}", fontsize=9)
    return _ret(fig, ax)


def plot_effect_response(diagnosis, effect=None, *, ax=None, n=4):
    """An effect's interpolated response against its magnitude, and the data it was fitted to.

    For the ``n`` calibration components the effect moves most (at its prior top), the
    whitened response (change / sigma) is drawn along the prior range through its simulated
    nodes: circles at the fingerprint's magnitudes, diamonds at magnitudes simulated later
    (refinement, or a rerun that contradicted the interpolation). Dotted lines in the same
    colours are what the effect has to supply there: the measured residual less the
    recalibration and any other effect of the fitted model. The vertical line and band are
    the fitted magnitude and its 95 % interval. A fit between nodes leans on the
    interpolation; where a dotted line crosses its curve far from any node, so does the
    magnitude.

    Parameters
    ----------
    diagnosis : Diagnosis
    effect : str, optional
        Default: the attributed effect, else the best candidate fitted alone.
    n : int
        Components drawn.

    Examples
    --------
    >>> import pathlib
    >>> import bedstruct.diagnose as dg
    >>> from bedstruct.diagnose import (BASE_PARAMETERS, SurrogateSimulator, catalogue, diagnose,
    ...                                 diagnosis_design, load_measurements)
    >>> ms = load_measurements(pathlib.Path(dg.__file__).parents[2] / "data/measurements/seed.toml")
    >>> sim = SurrogateSimulator(diagnosis_design(ms, catalogue()))
    >>> d = diagnose(ms, sim, base=BASE_PARAMETERS, replicates=2, refine=0)
    >>> fig, ax = plot_effect_response(d)
    >>> ax.get_xlabel()
    'missing_fines magnitude (1)'
    """
    att, fps = diagnosis.attribution, diagnosis.fingerprints
    effect = _leading_effect(att, effect, "plot_effect_response")
    fp = fps[effect]
    model = next((m for m in (att.best, *att.models) if effect in m.effects), None)
    fig, ax = _axes(ax)
    sig = fps.sigma
    rows = np.flatnonzero(fps.rows_calibrate)
    lo, top = fp.effect.prior
    strength = np.abs(fp.predict(top)[rows]) / sig[rows]
    pick = rows[np.argsort(-strength)[:max(int(n), 1)]]
    grid = np.linspace(min(lo, 0.0), top, 121)
    curve = np.array([fp.predict(a) for a in grid])
    target = diagnosis.residual.copy()
    if model is not None:
        if len(model.nuisance):
            target = target - fps.sensitivities @ np.asarray(model.nuisance, float)
        for e, a in zip(model.effects, model.magnitudes):
            if e != effect:
                target = target - fps[e].predict(float(a))
    names, labels = fps.design.component_names(), fps.design.component_labels()
    first = np.isin(fp.nodes, np.r_[0.0, fp.magnitudes])
    colors = [f"C{k}" for k in range(len(pick))]
    for i, c in zip(pick, colors):
        ax.plot(grid, curve[:, i] / sig[i], color=c, lw=1.2, label=f"{names[i]} [{labels[i]}]")
        ax.plot(fp.nodes[first], fp.responses[first, i] / sig[i], "o", color=c, ms=4)
        if (~first).any():
            ax.plot(fp.nodes[~first], fp.responses[~first, i] / sig[i], "D", color=c, ms=5,
                    mfc="white")
        if np.isfinite(target[i]):
            ax.axhline(target[i] / sig[i], color=c, ls=":", lw=1.0)
    if model is not None:
        k = list(model.effects).index(effect)
        a, (a_lo, a_hi) = float(model.magnitudes[k]), model.intervals[k]
        ax.axvspan(a_lo, a_hi, color="0.85", zorder=0)
        ax.axvline(a, color="k", lw=0.8)
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_xlabel(f"{effect} magnitude ({fp.effect.unit})")
    ax.set_ylabel("change / sigma (calibration components)")
    ax.legend(fontsize=6)
    ax.set_title(f"{effect}: circles simulated, diamonds simulated at fitted magnitudes; "
                 "dotted: data", fontsize=8)
    return _ret(fig, ax)


def plot_magnitude_profile(diagnosis, effect=None, *, ax=None):
    """The profile of chi-square over an effect's magnitude, and the interval read from it.

    At each magnitude over the prior the recalibration (and a partner effect of the chosen
    model) is refitted (:func:`~bedstruct.diagnose.profile_interval.profile_interval`); the
    curve is the chi-square above its lowest point, the dashed line the 95 % threshold, the
    band the interval and the vertical line the fitted magnitude. A flat curve says the data
    hardly tell magnitudes apart, however narrow the local slope at the optimum would make
    the interval look.

    Parameters
    ----------
    diagnosis : Diagnosis
    effect : str, optional
        Default: the attributed effect, else the best candidate fitted alone.

    Examples
    --------
    >>> import pathlib
    >>> import bedstruct.diagnose as dg
    >>> from bedstruct.diagnose import (BASE_PARAMETERS, SurrogateSimulator, catalogue, diagnose,
    ...                                 diagnosis_design, load_measurements)
    >>> ms = load_measurements(pathlib.Path(dg.__file__).parents[2] / "data/measurements/seed.toml")
    >>> sim = SurrogateSimulator(diagnosis_design(ms, catalogue()))
    >>> d = diagnose(ms, sim, base=BASE_PARAMETERS, replicates=2, refine=0)
    >>> fig, ax = plot_magnitude_profile(d)
    >>> ax.get_ylabel()
    'chi2 - min chi2 (calibration)'
    """
    att, fps = diagnosis.attribution, diagnosis.fingerprints
    effect = _leading_effect(att, effect, "plot_magnitude_profile")
    model = att.best if effect in att.best.effects else next(
        m for m in att.models if m.effects == (effect,))
    fitted = model.magnitude(effect)
    prof = profile_interval(diagnosis.residual, fps, model.effects, effect, fitted)
    fig, ax = _axes(ax)
    ax.plot(prof.magnitudes, prof.chi2 - prof.chi2.min(), color="k", lw=1.2)
    ax.axhline(prof.threshold, color="0.4", ls="--", lw=0.8)
    ax.axvspan(*prof.interval, color="0.85", zorder=0)
    ax.axvline(fitted, color="#c53030", lw=0.8)
    ax.set_xlabel(f"{effect} magnitude ({fps[effect].effect.unit})")
    ax.set_ylabel("chi2 - min chi2 (calibration)")
    ax.set_ylim(0.0, max(4.0 * prof.threshold, 1.0))
    ax.set_title(f"{model.label}: profile of chi2 (recalibration refitted at each magnitude); "
                 f"95 % interval {prof.interval[0]:.3g}-{prof.interval[1]:.3g}", fontsize=8)
    return _ret(fig, ax)


def plot_shrink(shrink, *, ax=None):
    """Held-out gap (RMS z) per observable: before, recalibrated only, after."""
    fig, ax = _axes(ax)
    rows = list(shrink.per_observable)
    x = np.arange(len(rows))
    w = 0.27
    for k, (key, c) in enumerate((("before", "#a0aec0"), ("recalibrated", "#63b3ed"),
                                  ("after", "#c53030"))):
        ax.bar(x + (k - 1) * w, [r[key] for r in rows], w, label=key, color=c)
    ax.axhline(1.0, color="0.4", ls="--", lw=0.8)
    ax.set_xticks(x)
    ax.set_xticklabels([r["observable"] for r in rows], rotation=45, ha="right", fontsize=7)
    ax.set_ylabel("RMS z on held-out components")
    ax.legend(fontsize=7)
    ax.set_title(f"how far: {shrink.model}", fontsize=9)
    return _ret(fig, ax)


def plot_confusion(validation, *, ax=None):
    """Confusion matrix of a ``ValidationResult`` (true rows, predicted top label columns)."""
    fig, ax = _axes(ax, (7.0, 5.0))
    c = validation.confusion
    M = np.asarray(c["matrix"], dtype=float)
    ax.imshow(M, cmap="Blues")
    for i in range(M.shape[0]):
        for j in range(M.shape[1]):
            if M[i, j]:
                ax.text(j, i, int(M[i, j]), ha="center", va="center", fontsize=7)
    ax.set_xticks(range(len(c["columns"])))
    ax.set_xticklabels(c["columns"], rotation=45, ha="right", fontsize=7)
    ax.set_yticks(range(len(c["rows"])))
    ax.set_yticklabels(c["rows"], fontsize=7)
    ax.set_xlabel("diagnosis (top label)")
    ax.set_ylabel("twin truth")
    return _ret(fig, ax)
