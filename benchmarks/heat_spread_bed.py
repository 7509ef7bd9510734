"""Seed section 2.4.2 on a spread bed: heat pulses at the start, centre and end regions.

Runs :func:`bedstruct.analysis.heat_study.heat_regions` on a bed made by the
spreading workflow (default: the bundled sample ``data/samples/spread``, the
``small`` preset after four layers; or any ``bed.dump.gz`` with its contacts
from ``bedstruct run spread``), prints the table of docs/heat.md beside the
seed's numbers, writes the figures ``docs/figures/heat_*.png`` and ends with
a ``RESULT`` line.

    python benchmarks/heat_spread_bed.py [--bed PATH --contacts PATH] [--figures DIR]
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

import bedstruct
from bedstruct.analysis.heat_study import heat_regions, heat_regions_table, planar_axes

ROOT = Path(__file__).resolve().parents[1]
SEED_PEAK_C = [342.0, 338.0, 348.0]        # reference-values.toml [heat], x1 rake speed
SEED_ROUNDNESS = [0.890, 0.975, 0.954]


def _maps_figure(res, vmin=20.0, vmax=360.0):
    from matplotlib.figure import Figure
    from matplotlib.patches import Ellipse
    fig = Figure(figsize=(10.5, 3.8), dpi=90, layout="constrained")
    axs = fig.subplots(1, len(res.names), sharey=False)
    axs = np.atleast_1d(axs)
    for ax, name, m, h in zip(axs, res.names, [m[0] for m in res.maps], [h[0] for h in res.haz]):
        c = m.source_center
        ext = (np.asarray(m.extent) - np.array([c[0], c[0], c[1], c[1]])) * 1e6   # um about the source
        im = ax.imshow(m.values - 273.15, origin="lower", extent=tuple(ext), cmap="inferno",
                       vmin=vmin, vmax=vmax, interpolation="nearest")
        xs = (m.x - c[0]) * 1e6
        ys = (m.y - c[1]) * 1e6
        ax.contour(xs, ys, h.mask.astype(float), levels=[0.5], colors="cyan", linewidths=1.2)
        ax.add_patch(Ellipse(tuple((h.centroid - c) * 1e6), h.major_axis * 1e6, h.minor_axis * 1e6,
                             angle=h.orientation_deg, fill=False, color="lime", lw=1.2, ls="--"))
        ax.set_title(f"{name}: peak {res.peak_temperature[list(res.names).index(name), 0] - 273.15:.0f} C,"
                     f" R = {h.roundness:.2f}", fontsize=9)
        ax.set_xlabel("x - x_source (um)")
        ax.set_aspect("equal")
    axs[0].set_ylabel("y - y_source (um)")
    fig.colorbar(im, ax=list(axs), label="temperature (C)", shrink=0.85)
    fig.suptitle(f"top view at t = {res.time * 1e3:.1f} ms (first source of each region); cyan: HAZ outline at "
                 f"{res.threshold_fraction:.0%} of (T_max - T0), green: equal-moment ellipse", fontsize=9)
    return fig


def _cooling_figure(res):
    from matplotlib.figure import Figure
    fig = Figure(figsize=(5.5, 3.8), dpi=90, layout="constrained")
    ax = fig.add_subplot()
    for k, (name, tt, pp) in enumerate(zip(res.names, res.history_times, res.history_peak)):
        for q, (t, p) in enumerate(zip(tt, pp)):
            ax.plot(t * 1e3, p - 273.15, "-", lw=1.5 if q == 0 else 0.6, color=f"C{k}",
                    label=name if q == 0 else None)
    stop = res.initial_temperature + res.stop_fraction * (res.source_temperature - res.initial_temperature)
    ax.axhline(stop - 273.15, color="k", lw=0.8, ls=":", label=f"stop level ({res.stop_fraction:.0%} of pulse excess)")
    ax.axvline(res.time * 1e3, color="k", lw=0.8, ls="--", label=f"end time {res.time * 1e3:.1f} ms")
    for k, v in enumerate(SEED_PEAK_C):
        ax.plot([res.time * 1e3], [v], "x", color=f"C{k}", ms=7)
    ax.set_ylim(200, 1350)
    ax.set_xlabel("time (ms)")
    ax.set_ylabel("hottest particle (C)")
    ax.set_title("cooling after the 1300 C pulse (x: seed peaks)", fontsize=9)
    ax.legend(fontsize=7)
    return fig


def _tensor_figure(res):
    from matplotlib.figure import Figure
    fig = Figure(figsize=(10.5, 4.4), dpi=90)
    fig.subplots_adjust(top=0.76, bottom=0.16, wspace=0.45)
    th = np.linspace(0, 2 * np.pi, 361)
    n = np.stack([np.cos(th), np.sin(th)], 1)
    for k, (name, kt, hs) in enumerate(zip(res.names, res.conductivity, res.haz)):
        ax = fig.add_subplot(1, len(res.names), k + 1, projection="polar")
        kk = np.einsum("ni,ij,nj->n", n, kt.tensor[:2, :2], n)
        ff = np.einsum("ni,ij,nj->n", n, kt.fabric[:2, :2], n)
        ax.plot(th, kk / kk.mean(), color="C0", lw=1.8, label="conductivity n.K.n")
        ax.plot(th, ff / ff.mean(), color="C1", lw=1.8, label="fabric n.N.n")
        for q, h in enumerate(hs):        # HAZ ellipse radius along each direction, each source
            a, b, phi = h.major_axis / 2, h.minor_axis / 2, h.orientation
            u = th - phi
            rh = a * b / np.sqrt((b * np.cos(u)) ** 2 + (a * np.sin(u)) ** 2)
            ax.plot(th, rh / rh.mean(), color="C2", lw=0.9, alpha=0.8,
                    label="HAZ ellipse radius (each source)" if q == 0 else None)
        ax.set_rlim(0.5, 1.5)
        ax.set_rticks([0.6, 1.0, 1.4])
        ax.tick_params(labelsize=7)
        ang, rk = planar_axes(kt.tensor)
        rr = np.array([h.roundness for h in hs])
        ax.set_title(f"{name}: K roundness {rk:.3f}, major at {ang:.0f} deg\nHAZ R {rr.mean():.2f} +- "
                     f"{rr.std():.2f} ({len(hs)} sources)", fontsize=8, pad=14)
    fig.legend(*fig.axes[0].get_legend_handles_labels(), fontsize=7, loc="lower center", ncol=3)
    fig.suptitle("in-plane directional conductivity, contact fabric and HAZ (each / its mean)", fontsize=9)
    return fig


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bed", default=str(ROOT / "data/samples/spread/bed.dump.gz"))
    ap.add_argument("--contacts", default=str(ROOT / "data/samples/spread/contacts.dump.gz"))
    ap.add_argument("--figures", default=str(ROOT / "docs/figures"))
    ap.add_argument("--no-figures", action="store_true")
    ap.add_argument("--sources", type=int, default=4, help="pulses per region (across the strip)")
    ap.add_argument("--no-sensitivity", action="store_true")
    a = ap.parse_args(argv)
    tr = bedstruct.read_dump(a.bed, units="si")
    frame = tr[len(tr) - 1]
    contacts = bedstruct.read_dump_local(a.contacts, frames=tr)[frame.timestep]
    t0 = time.perf_counter()
    res = heat_regions(frame, contacts, n_sources=a.sources)
    wall = time.perf_counter() - t0
    tab = heat_regions_table(res)
    print(f"bed: {frame.n_particles} particles, {len(contacts.i)} contacts; tiles {res.tiles} "
          f"({res.network.n_particles} particles in the pulse runs); {a.sources} sources per region; "
          f"end time {res.time * 1e3:.2f} ms; {wall:.1f} s")
    print("| region | peak T (C) bedstruct | seed | roundness bedstruct | seed | HAZ angle (deg) "
          "| K roundness | K angle (deg) | fabric ratio | fabric angle (deg) | k_min-k_max (W/m K) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for k, name in enumerate(res.names):
        sp = SEED_PEAK_C[k] if len(res.names) == 3 else math.nan
        sr = SEED_ROUNDNESS[k] if len(res.names) == 3 else math.nan
        print(f"| {name} | {tab['peak_temperature_C'][k]:.0f} +- {tab['peak_temperature_std'][k]:.0f} | {sp:.0f} "
              f"| {tab['roundness'][k]:.2f} +- {tab['roundness_std'][k]:.2f} | {sr:.3f} "
              f"| {tab['orientation_deg'][k]:.0f} | {tab['k_roundness'][k]:.3f} | {tab['k_orientation_deg'][k]:.0f} "
              f"| {tab['fabric_ratio'][k]:.3f} | {tab['fabric_orientation_deg'][k]:.0f} "
              f"| {tab['k_min'][k]:.3f}-{tab['k_max'][k]:.3f} |")
    # sensitivity of the roundness to the unstated settings: outline level and map rendering from the
    # stored end temperatures (all sources); end time and tiling by rerunning (one source per region)
    print("\nroundness sensitivity (start, centre, end; mean +- std over sources):")
    from bedstruct.analysis.heat import haz_shape, temperature_map
    T0 = res.initial_temperature
    for label, q, method in [("outline 30 %", 0.3, "top"), ("outline 70 %", 0.7, "top"),
                             ("map linear", 0.5, "linear"), ("map max", 0.5, "max")]:
        rr = np.empty(res.roundness.shape)
        for k in range(rr.shape[0]):
            for s in range(rr.shape[1]):
                m0 = res.maps[k][s]
                m = temperature_map(res.network, temperature=res.temperatures[k, s], cell=m0.cell,
                                    extent=m0.extent, method=method)
                rr[k, s] = haz_shape(m, T0 + q * (np.nanmax(m.values) - T0), center=m0.source_center).roundness
        print(f"| {label} | " + " | ".join(f"{m:.2f} ± {d:.2f}" for m, d in zip(rr.mean(1), rr.std(1))) + " | |")
    base1 = heat_regions(frame, contacts, n_sources=1) if not a.no_sensitivity else None
    if base1 is not None:
        print(f"| one source at the window centre | " + " | ".join(f"{v:.2f}" for v in base1.roundness[:, 0])
              + " | " + " / ".join(f"{v - 273.15:.0f}" for v in base1.peak_temperature[:, 0]) + " |")
    for label, kw in [("stop 15 %", {"stop_fraction": 0.15}), ("stop 40 %", {"stop_fraction": 0.40}),
                      ("tiles x10", {"tiles": (1, 10, 1)})] * (not a.no_sensitivity):
        r = heat_regions(frame, contacts, n_sources=1, **kw)
        print(f"| one source, {label} | " + " | ".join(f"{v:.2f}" for v in r.roundness[:, 0])
              + " | " + " / ".join(f"{v - 273.15:.0f}" for v in r.peak_temperature[:, 0]) + " |")
    if not a.no_figures:
        out = Path(a.figures)
        out.mkdir(parents=True, exist_ok=True)
        for name, fig in [("heat_regions_maps", _maps_figure(res)), ("heat_regions_cooling", _cooling_figure(res)),
                          ("heat_regions_tensors", _tensor_figure(res))]:
            p = out / f"{name}.png"
            fig.savefig(p)
            print(f"wrote {p} ({p.stat().st_size / 1e3:.0f} kB)")
    print("RESULT " + " ".join([f"n_particles={frame.n_particles}", f"tiled_particles={res.network.n_particles}",
                                f"end_time_ms={res.time * 1e3:.3f}", f"wall_s={wall:.2f}"]
                               + [f"peak_C_{n}={v:.1f}" for n, v in zip(res.names, tab['peak_temperature_C'])]
                               + [f"roundness_{n}={v:.3f}" for n, v in zip(res.names, tab['roundness'])]
                               + [f"k_roundness_{n}={v:.3f}" for n, v in zip(res.names, tab['k_roundness'])]))


if __name__ == "__main__":
    main()
