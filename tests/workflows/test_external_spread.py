"""Spreading on LIGGGHTS and LAMMPS: the roller, and contact histories kept across layers.

All layers run in one engine run (``bedstruct.engines.spread_layers_deck``). Each
engine's tests skip when it is not installed (``bash .ci/install-engines.sh``).
"""

import gzip
import json

import numpy as np
import pytest

from bedstruct.engines import find_lammps, find_liggghts
from bedstruct.io import read_dump
from bedstruct.workflows import load_config, run_spread

from _runfiles import run_files, without_times

ENGINES = {"liggghts": find_liggghts, "lammps": find_lammps}


def _need(engine):
    if ENGINES[engine]() is None:
        pytest.skip(f"{engine} is not installed (bash .ci/install-engines.sh)")


def _local_blocks(path):
    """{timestep: (M, ncol) array} of a LAMMPS/LIGGGHTS local dump (plain or gzip)."""
    op = gzip.open if str(path).endswith(".gz") else open
    out, step, rows, mode = {}, None, [], None
    with op(path, "rt") as fh:
        for line in fh:
            if line.startswith("ITEM:"):
                if step is not None and mode == "rows":
                    out[step] = np.array(rows, float).reshape(len(rows), -1)
                mode = {"ITEM: TIMESTEP": "step"}.get(line.strip(), "rows"
                                                      if line.startswith("ITEM: ENTRIES") else None)
                if mode == "step":
                    step, rows = None, []
                continue
            if mode == "step":
                step = int(line)
            elif mode == "rows":
                rows.append(line.split())
    if step is not None:
        out[step] = np.array(rows, float).reshape(len(rows), -1)
    return out


def _tangential_liggghts(block, width, n_max):
    """{(i, j): |F_t|} of particle pairs (ids <= n_max) from LIGGGHTS ``pos id force ...``."""
    x1, x2, ids, f = block[:, 0:3], block[:, 3:6], block[:, 6:8].astype(int), block[:, 9:12]
    d = x2 - x1
    d[:, 1] -= width * np.round(d[:, 1] / width)                  # periodic y
    n = d / np.linalg.norm(d, axis=1)[:, None]
    ft = np.linalg.norm(f - np.einsum("ij,ij->i", f, n)[:, None] * n, axis=1)
    fn = np.abs(np.einsum("ij,ij->i", f, n))
    keep = (ids.max(axis=1) <= n_max)
    return {(int(min(a, b)), int(max(a, b))): (t, m)
            for (a, b), t, m, k in zip(ids, ft, fn, keep) if k}


def _roller_cfg(engine):
    return load_config(preset="tiny", overrides=[
        "contact.cohesion=0.0", f"engine={engine}", "spread.tool=roller", "spread.gaps=[4.5e-4]",
        "spread.n_frames=2", "spread.pile_particles=650", "spread.pile_time=0.006",
        "spread.plate_length=1.6e-3", "spread.pile_length=1.0e-3"])


@pytest.fixture(scope="module")
def embedded_roller(tmp_path_factory):
    return run_spread(_roller_cfg("embedded"), out=tmp_path_factory.mktemp("roller"))


def _tangential_lammps(block, n_max):
    """{(i, j): (|F_t|, |F_n|)} of touching particle pairs (ids <= n_max) from LAMMPS'
    ``patom1 patom2 dist fx fy fz p1 p2 p3`` (pair granular: normal force, tangential force)."""
    ids = block[:, 0:2].astype(int)
    fn = np.linalg.norm(block[:, 3:6], axis=1)
    ft = np.linalg.norm(block[:, 6:9], axis=1)
    keep = (ids.max(axis=1) <= n_max) & (fn > 0)
    return {(int(min(a, b)), int(max(a, b))): (t, m)
            for (a, b), t, m, k in zip(ids, ft, fn, keep) if k}


def _history_kept(out, width, n, tangential):
    """Tangential forces of the bed at the end of layer 1 and as layer 2 starts."""
    end = _local_blocks(out / "layer01" / "contacts.dump.gz")
    start = _local_blocks(out / "layer02" / "start_contacts.dump.gz")
    a, b = tangential(end[max(end)]), tangential(start[max(start)])
    common = [k for k in a if k in b and a[k][0] > 0.05 * a[k][1]]
    assert len(common) > 0.5 * len(a) > 100
    ft_end = np.array([a[k][0] for k in common])
    ft_start = np.array([b[k][0] for k in common])
    return np.median(ft_start / ft_end), np.median(np.abs(ft_start - ft_end) / ft_end)


@pytest.mark.parametrize("engine", sorted(ENGINES))
def test_roller_one_layer(tmp_path, engine, embedded_roller):
    """The counter-rotating roller (surface speed = traverse speed) spreads a bed no thicker
    than the gap plus a particle; every sphere is accounted for (bed + heap + removed =
    inserted); the bed is that of the embedded engine's roller within 40 % in spheres and a
    factor of 2 in mean height (one pile each; measured, docs/validation.md: mean height
    211 / 304 / 193 um on embedded / LIGGGHTS / LAMMPS, and 228 / 293 / 247 um without spin:
    the faceted STL roller leaves a thicker bed than the analytic cylinders, spin or not; one
    embedded pile alone gives 155, 170, 181 and 251 um over seeds 0-3)."""
    _need(engine)
    res = run_spread(_roller_cfg(engine), out=tmp_path)
    (layer,) = res.layers
    (ref,) = embedded_roller.layers
    assert res.tool == "roller" and layer.n_inserted == res.n_pile == 650
    assert layer.n_bed + layer.n_heap + layer.n_removed == layer.n_inserted
    H = layer.nominal_height
    assert layer.n_bed > 120 and layer.n_removed > 0        # a bed forms, the excess goes over
    assert 0.25 * H < layer.bed_height_m < layer.bed_top_m < H + 140e-6
    assert all(0.2 < f < 0.66 for f in layer.packing_fraction)
    assert layer.n_bed == pytest.approx(ref.n_bed, rel=0.4), (layer.n_bed, ref.n_bed)
    assert 0.5 < layer.bed_height_m / ref.bed_height_m < 2.0, (layer.bed_height_m,
                                                               ref.bed_height_m)
    d = json.loads((tmp_path / "results.json").read_text())
    assert d["engine"] == engine and d["tool"] == "roller"
    deck = (tmp_path / "in.spread").read_text()
    assert ("rotate origin" in deck) if engine == "liggghts" else ("rotate v_th" in deck)
    # the stroke-averaged load on the roller (LIGGGHTS: the mesh/surface/stress force; LAMMPS:
    # the summed per-atom forces of wall/gran/region ... contacts; both averaged over the steps
    # by fix ave/time) has the embedded engine's sign and order of magnitude: one pile each,
    # the x load varies 2.7-fold over seeds 0-3 on the embedded roller alone, and LIGGGHTS'
    # faceted roller carried 0.31, 0.12, 0.39 and 0.52 of the embedded one's
    assert layer.tool_force[0] < 0 and ref.tool_force[0] < 0
    assert 1 / 10 < layer.tool_force[0] / ref.tool_force[0] < 3, (layer.tool_force,
                                                                  ref.tool_force)


def _two_layer_cfg(engine, small: bool, *extra):
    extra = (["spread.pile_particles=400", "spread.pile_time=0.005", "spread.plate_length=1.6e-3",
              "spread.pile_length=1.0e-3", "spread.n_frames=2"] if small else ["spread.n_frames=3"]
             ) + list(extra)
    return load_config(preset="tiny", overrides=["contact.cohesion=0.0", f"engine={engine}",
                                                 *extra])


@pytest.fixture(scope="module")
def liggghts_two_layers(tmp_path_factory):
    """The small two-layer LIGGGHTS run, uninterrupted (its pile checkpoints every 5000 of
    its ~21000 steps: the checkpoints change nothing in the results)."""
    _need("liggghts")
    cfg = _two_layer_cfg("liggghts", True, "output.checkpoint_every=5000")
    out = tmp_path_factory.mktemp("two-layers")
    return cfg, run_spread(cfg, out=out), out


def test_liggghts_keeps_contact_histories_between_layers(liggghts_two_layers):
    """Two layers in one LIGGGHTS run. The bed at rest at the start of layer 2 (before the
    platform moves) carries the tangential contact forces it had at the end of layer 1:
    static friction lives in the tangential springs, which a deck per layer (restarted
    histories) set back to zero. Every sphere is accounted for in both layers."""
    cfg, res, tmp_path = liggghts_two_layers
    assert len(res.layers) == 2 and res.n_inserted_total == 2 * res.n_pile == 800
    inserted = 0
    for layer in res.layers:
        inserted += layer.n_inserted
        assert layer.n_bed + layer.n_heap + layer.n_removed == inserted
    assert res.layers[1].n_bed > res.layers[0].n_bed > 100
    W, n = float(cfg["spread"]["width"]), res.n_pile
    ratio, change = _history_kept(tmp_path, W, n, lambda b: _tangential_liggghts(b, W, n))
    # kept: the same forces up to the bed's slow relaxation while the tool returns (the
    # normal forces change as much: 10-90 % of their ratios 0.69-1.49 in the 800-sphere
    # run); restarted: ratio ~0, change ~1. Measured: median ratio 0.94 and median relative
    # change 0.39 (these 400-sphere piles), 0.95 and 0.29 (800), 0.99 and 0.07 (300)
    assert 0.7 < ratio < 1.3
    assert change < 0.6


def test_liggghts_spread_writes_the_embedded_engines_layer_layout(liggghts_two_layers):
    """Each layer folder holds ``bed.dump.gz``: the spheres on the platform after the layer
    (what the diagnosis reads for the PSD after spreading), as the embedded engine writes
    it; the whole state, ``final.dump.gz``, is written after the last layer only."""
    cfg, res, out = liggghts_two_layers
    lplat = float(cfg["spread"]["plate_length"])
    for k, layer in enumerate(res.layers):
        stage = out / f"layer{k + 1:02d}"
        bed = read_dump(stage / "bed.dump.gz")[0]
        x = np.asarray(bed.positions)[:, 0]
        assert bed.n_particles >= layer.n_bed and np.all(x < lplat)
        assert (stage / "final.dump.gz").exists() == (k == len(res.layers) - 1)
    final = read_dump(out / f"layer{len(res.layers):02d}" / "final.dump.gz")[0]
    assert set(np.asarray(bed.ids).tolist()) <= set(np.asarray(final.ids).tolist())


class Killed(BaseException):
    """Stands for a kill: nothing in the workflows catches it."""


def _files(root):
    """The run folder's files, without those that hold paths or times (deck, log, marker,
    results)."""
    return run_files(root, skip=("in.log", "in.spread", "run.json", "results.json",
                                 ".bedstruct.lock"))


def test_killed_liggghts_spread_reuses_its_pile_and_finished_engine_run(liggghts_two_layers,
                                                                        tmp_path, monkeypatch):
    """The same call resumes a killed run: killed while the pile settles (it goes on from
    pile/progress.npz), then as the engine starts (a cut log and dump of layer 1 are left:
    the engine runs again from its start, its earlier output removed), then while layer 2
    is measured (the finished engine run is reused, not run again). The results and files
    equal the uninterrupted run's (LIGGGHTS at np=1 is bit-for-bit deterministic: two runs
    give the same dumps and results); a complete run then runs nothing at all."""
    import bedstruct.workflows.external_spread as external_spread
    import bedstruct.workflows.spread_pile as spread_pile
    from bedstruct.dem import Simulation
    cfg, ref, ref_out = liggghts_two_layers
    out = tmp_path / "run"
    calls = {"pile": 0, "engine": 0, "measure": 0}
    gen, deck, meas = (spread_pile.generate_pile, external_spread.run_deck,
                       external_spread.measure_layer)

    def count(key, fn):
        def wrapped(*a, **kw):
            calls[key] += 1
            return fn(*a, **kw)
        return wrapped
    monkeypatch.setattr(spread_pile, "generate_pile", count("pile", gen))

    def run_killed(**patches):
        for key in calls:
            calls[key] = 0
        with monkeypatch.context() as m:
            for name, (obj, fn) in patches.items():
                m.setattr(obj, name, fn)
            with pytest.raises(Killed):
                run_spread(cfg, out=out)
        assert json.loads((out / "run.json").read_text())["status"] == "running"
        assert not (out / "results.json").exists()

    # 1. killed while the pile settles, after its first checkpoint
    run = Simulation.run

    def pile_killed(sim, *a, **kw):
        stats = run(sim, *a, **kw)
        if (out / "pile" / "progress.npz").is_file():
            raise Killed
        return stats
    run_killed(run=(Simulation, pile_killed))
    assert not (out / "pile" / "pile.dump.gz").exists()

    # 2. killed as the engine runs: what it leaves is a cut log and a cut dump
    def engine_killed(deck_path, **kw):
        calls["engine"] += 1
        root = kw["cwd"]
        (root / "in.log").write_text("LIGGGHTS (Version)\nBEDSTRUCT_OFFSET layer=1 steps=0\n")
        (root / "layer01" / "frames.dump").write_text("ITEM: TIMESTEP\n0\nITEM: NUMBER OF")
        raise Killed
    run_killed(run_deck=(external_spread, engine_killed))
    assert calls["pile"] == 1 and (out / "pile" / "pile.dump.gz").is_file()
    assert not (out / "pile" / "progress.npz").exists()

    # 3. the engine runs again from its start; killed while layer 2 is measured
    def measure_killed(*a, **kw):
        calls["measure"] += 1
        if kw["index"] == 2:
            raise Killed
        return meas(*a, **kw)
    run_killed(run_deck=(external_spread, count("engine", deck)),
               measure_layer=(external_spread, measure_killed))
    assert (calls["pile"], calls["engine"], calls["measure"]) == (0, 1, 2)

    # 4. resumed: neither the pile nor the engine run again; only the measurement
    for key in calls:
        calls[key] = 0
    monkeypatch.setattr(external_spread, "run_deck", count("engine", deck))
    monkeypatch.setattr(external_spread, "measure_layer", count("measure", meas))
    res = run_spread(cfg, out=out)
    assert (calls["pile"], calls["engine"], calls["measure"]) == (0, 0, 2)
    assert without_times(res.to_dict()) == without_times(ref.to_dict())
    assert _files(out) == _files(ref_out)
    assert json.loads((out / "run.json").read_text())["status"] == "complete"

    # 5. complete: the results come back from results.json, nothing runs
    for key in calls:
        calls[key] = 0
    again = run_spread(cfg, out=out)
    assert calls == {"pile": 0, "engine": 0, "measure": 0}
    assert again.to_dict() == res.to_dict()
    assert json.loads((out / "run.json").read_text())["status"] == "complete"


def test_an_engine_run_counts_as_finished_only_with_its_end_marker_and_whole_dumps(tmp_path):
    """No engine needed: the check that lets a resumed run reuse the engine's output."""
    from bedstruct.core import Frame
    from bedstruct.engines import BladeGeometry, SpreadLayersPlan
    from bedstruct.io import write_dump
    from bedstruct.workflows.external import _gzip
    from bedstruct.workflows.external_spread import _engine_finished
    blade = BladeGeometry(x0=0.0, z_bottom=0.0, speed=0.1, height=1e-3)
    plan = SpreadLayersPlan(3e-3, 2e-3, (2e-4, 2e-4), blade, ((1, 1), (2, 2)), (0.0, 5e-3),
                            (5e-4, 1.5e-3), 1e-6, x_end=3.5e-3, n_frames=4, settle_time=5e-3)
    shift = 300
    ends = [ls.end for ls in plan.shifted((0, shift))]
    log = tmp_path / "in.log"
    log.write_text("BEDSTRUCT_OFFSET layer=1 steps=0\nBEDSTRUCT_OFFSET layer=2 steps=300\n")
    for k, end in enumerate(ends):
        stage = tmp_path / f"layer{k + 1:02d}"
        stage.mkdir()
        frames = [Frame(np.full((1, 3), 5e-4), [1e-5], box=[1e-3, 1e-3, 1e-3], timestep=t)
                  for t in (end - 100, end)]
        write_dump(stage / "frames.dump", frames)
        for name in ("contacts.dump", "start.dump", "start_contacts.dump")[:1 + 2 * (k > 0)]:
            (stage / name).write_text("x\n")
    assert not _engine_finished(tmp_path, plan, contacts=True)     # no end marker: killed
    with open(log, "a") as fh:
        fh.write("BEDSTRUCT_DONE layer=2\n")
    assert _engine_finished(tmp_path, plan, contacts=True)
    _gzip(tmp_path / "layer01" / "frames.dump")          # compressed by a killed measurement
    assert _engine_finished(tmp_path, plan, contacts=True)
    frames2 = tmp_path / "layer02" / "frames.dump"
    text = frames2.read_text()
    frames2.write_text(text[:len(text) - 40])             # the last frame cut off
    assert not _engine_finished(tmp_path, plan, contacts=True)
    frames2.write_text(text)
    assert _engine_finished(tmp_path, plan, contacts=True)
    (tmp_path / "layer02" / "start_contacts.dump").unlink()
    assert not _engine_finished(tmp_path, plan, contacts=True)
    assert _engine_finished(tmp_path, plan, contacts=False)   # no contact dumps asked for
    (tmp_path / "layer02" / "start.dump").unlink()
    assert not _engine_finished(tmp_path, plan, contacts=False)


@pytest.mark.slow
def test_liggghts_two_tiny_layers(tmp_path):
    """The tiny preset's two layers on LIGGGHTS: the bevelled blade spreads each layer no
    thicker than the blade height above the platform; conservation; histories kept."""
    _need("liggghts")
    cfg = _two_layer_cfg("liggghts", small=False)
    res = run_spread(cfg, out=tmp_path)
    assert len(res.layers) == 2 and res.n_inserted_total == 2 * res.n_pile
    inserted = 0
    for layer in res.layers:
        inserted += layer.n_inserted
        assert layer.n_bed + layer.n_heap + layer.n_removed == inserted
        H = layer.nominal_height
        assert 0.6 * H < layer.bed_height_m < layer.bed_top_m < 1.15 * H
        assert layer.bed_top_m > 0.85 * H
        assert all(0.4 < f < 0.66 for f in layer.packing_fraction)
        assert all(2.5 < c < 6.5 for c in layer.coordination)
    assert res.layers[1].n_bed > res.layers[0].n_bed
    d = json.loads((tmp_path / "results.json").read_text())
    assert d["engine"] == "liggghts" and len(d["layers"]) == 2
    W, n = float(cfg["spread"]["width"]), res.n_pile
    ratio, change = _history_kept(tmp_path, W, n, lambda b: _tangential_liggghts(b, W, n))
    assert 0.7 < ratio < 1.3 and change < 0.6


@pytest.mark.slow
def test_lammps_keeps_contact_histories_between_layers(tmp_path):
    """As the LIGGGHTS test, on LAMMPS (pair granular's tangential force, p1-p3)."""
    _need("lammps")
    res = run_spread(_two_layer_cfg("lammps", small=False), out=tmp_path)
    n = res.n_pile
    ratio, change = _history_kept(tmp_path, 0.0, n, lambda b: _tangential_lammps(b, n))
    assert 0.7 < ratio < 1.3      # measured 0.96 (change 0.30)
    assert change < 0.6


def test_liggghts_fast_stroke_waits_for_thrown_powder_to_land(tmp_path):
    """At the scale models' x5 speed (0.5 m/s) the stroke of layer 1 throws powder up; the
    LIGGGHTS deck waits, as the embedded run does (both 12 ms with these 400-sphere piles,
    three intervals), before placing the pile of layer 2. The frames of layer 2 are matched
    to the tool by the schedule shifted by the logged wait: the tool positions are those
    of a stroke starting at the front of the platform, as in layer 1."""
    _need("liggghts")
    cfg = load_config(preset="tiny", overrides=[
        "spread.speed=0.5", "time.v_max=0.75", "engine=liggghts", "spread.pile_particles=400",
        "spread.pile_time=0.005", "spread.plate_length=1.6e-3", "spread.pile_length=1.0e-3",
        "spread.n_frames=4"])
    res = run_spread(cfg, out=tmp_path)
    settle = float(cfg["spread"]["settle_time"])
    first, second = res.layers
    assert first.landing_wait == 0.0
    assert settle * 0.99 <= second.landing_wait <= 20 * settle * 1.01
    # the stroke-averaged load is recorded for every layer; the first pushes the powder (at
    # this speed the tool of the second is pushed forward on balance, on the embedded engine
    # as well: +1.4e-4 N there, +3.5e-4 N here)
    assert all(np.all(np.isfinite(layer.tool_force)) for layer in res.layers)
    assert first.tool_force[0] < 0
    assert second.blade_positions == pytest.approx(first.blade_positions, rel=1e-9)
    inserted = 0
    for layer in res.layers:
        inserted += layer.n_inserted
        assert layer.n_bed + layer.n_heap + layer.n_removed == inserted
    log = (tmp_path / "in.log").read_text()
    assert "BEDSTRUCT_OFFSET layer=2 steps=0" not in log


def test_platform_mesh_is_square_strips_covering_the_platform(tmp_path):
    from bedstruct.engines import read_stl_triangles
    from bedstruct.engines._stl import _chamber_meshes
    L, W, z = 6.0e-3, 0.6e-3, -4.5e-4
    tri = read_stl_triangles(_chamber_meshes(tmp_path, L, W, z, 1e-3)["platform"])
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    assert area.sum() == pytest.approx(L * W, rel=1e-9) and np.allclose(tri[..., 2], z)
    extent = tri[..., 0].max(axis=1) - tri[..., 0].min(axis=1)
    assert extent.max() <= W * (1 + 1e-9) and tri[..., 0].min() == 0.0
    assert tri[..., 0].max() == pytest.approx(L)


def test_liggghts_runs_a_long_platform(tmp_path):
    """LIGGGHTS 3.8 stopped ('assertion failed', region_neighbor_list_I.h) on a 6 mm platform
    written as two long triangles; the strips run."""
    _need("liggghts")
    cfg = load_config(preset="tiny", overrides=[
        "engine=liggghts", "spread.gaps=[4.5e-4]", "spread.n_frames=2", "spread.pile_particles=300",
        "spread.pile_length=0.5e-3", "spread.plate_length=6e-3", "output.contacts=false"])
    res = run_spread(cfg, out=tmp_path)
    assert len(res.layers) == 1 and res.layers[0].n_bed > 0
