"""Spreading between side walls (``spread.side_walls``): the embedded run, its pile and the
LIGGGHTS/LAMMPS decks."""

import json

import numpy as np
import pytest

from bedstruct.engines import (BladeGeometry, SpreadLayersPlan, find_lammps, find_liggghts,
                               spread_layers_deck, write_sphere_data)
from bedstruct.io import read_dump
from bedstruct.workflows import load_config, run_spread

W = 0.5e-3   # the distance between the walls: a few particles across

_SMALL = ["spread.gaps=[4.5e-4]", "spread.n_frames=3", "spread.pile_particles=300",
          "spread.pile_time=0.004", "spread.plate_length=1.2e-3", "spread.pile_length=0.6e-3",
          f"spread.width={W}"]


def _assert_between_walls(frame, width):
    """Every centre lies between the walls, every sphere within 5 % of its radius of them
    (the walls' contact overlap)."""
    y, r = frame.positions[:, 1], frame.radii
    assert frame.n_particles > 0
    assert np.all((y > 0) & (y < width))
    assert np.all(y - r > -0.05 * r) and np.all(y + r < width + 0.05 * r)


@pytest.fixture(scope="module")
def walled_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("walled")
    cfg = load_config(preset="tiny", overrides=[*_SMALL, "spread.side_walls=true"])
    return cfg, run_spread(cfg, out=out), out


def test_side_walls_keep_the_powder_between_them(walled_run):
    cfg, res, out = walled_run
    assert not read_dump(out / "pile" / "pile.dump.gz")[0].box.periodic[1]
    _assert_between_walls(read_dump(out / "pile" / "pile.dump.gz")[0], W)
    frames = read_dump(out / "layer01" / "frames.dump.gz")
    assert len(frames) == 3
    for fr in frames:
        _assert_between_walls(fr, W)
    _assert_between_walls(read_dump(out / "layer01" / "bed.dump.gz")[0], W)
    layer = res.layers[0]
    assert layer.n_bed > 0 and layer.n_bed + layer.n_heap + layer.n_removed == layer.n_inserted


def test_side_walls_carry_the_powder_s_load(walled_run):
    """Both walls touch powder in every frame; the powder pushes each outwards."""
    _, _, out = walled_run
    rows = [json.loads(s) for s in (out / "layer01" / "walls.jsonl").read_text().splitlines()]
    names = {r["name"] for r in rows}
    assert {"platform", "back", "tool", "front", "side_ylo", "side_yhi"} == names
    lo = [r for r in rows if r["name"] == "side_ylo"]
    hi = [r for r in rows if r["name"] == "side_yhi"]
    assert len(lo) == len(hi) == 3
    assert all(r["n_contacts"] > 0 for r in lo + hi)
    assert np.mean([r["force"][1] for r in lo]) < 0 < np.mean([r["force"][1] for r in hi])


def _plan(tmp_path, side_walls):
    f = write_sphere_data(tmp_path / "a.data", [[1e-3, 2e-4, -1e-4], [1e-3, 2e-4, 3e-3]],
                          [5e-5, 5e-5], box_lo=[-1e-3, 0, -1e-3], box_hi=[5e-3, 4e-4, 4e-3],
                          n_types=2)
    blade = BladeGeometry(x0=0.0, z_bottom=0.0, speed=0.1, height=1e-3)
    plan = SpreadLayersPlan(3e-3, 4e-4, (2e-4,), blade, ((1, 2),), (0.0,), (5e-4, 2e-3), 1e-6,
                            x_end=3.5e-3, n_frames=4, side_walls=side_walls)
    return f, plan


@pytest.mark.parametrize("engine, walls", [
    ("liggghts", ["primitive type 2 yplane 0.0", "primitive type 2 yplane 0.0004"]),
    ("lammps", ["yplane 0.0 0.0004"])])
def test_the_decks_write_the_side_walls(tmp_path, engine, walls):
    f, plan = _plan(tmp_path, True)
    deck = spread_layers_deck(f, engine=engine, plan=plan, stl_folder=tmp_path)
    lines = deck.splitlines()
    assert "boundary f f f" in lines
    side = [ln for ln in lines if "yplane" in ln]
    assert len(side) == len(walls)
    for ln, end in zip(side, walls):
        assert ln.startswith("fix w") and " wall/gran " in ln and ln.endswith(end)
    f, plan = _plan(tmp_path, False)
    open_deck = spread_layers_deck(f, engine=engine, plan=plan, stl_folder=tmp_path)
    assert "boundary f p f" in open_deck.splitlines() and "yplane" not in open_deck
    assert open_deck.count("\n") + len(walls) == deck.count("\n")


def test_the_external_spread_deck_has_the_side_walls(tmp_path):
    cfg = load_config(preset="tiny", overrides=[
        *_SMALL, "spread.pile_particles=100", "spread.side_walls=true", "engine=liggghts",
        "external.write_only=true"])
    res = run_spread(cfg, out=tmp_path)
    deck = (tmp_path / "in.spread").read_text().splitlines()
    assert res.decks == (str(tmp_path / "in.spread"),)
    assert "boundary f f f" in deck
    assert [ln.split()[-1] for ln in deck if "yplane" in ln] == ["0.0", f"{W:.10g}"]


@pytest.mark.parametrize("engine", ["liggghts", "lammps"])
def test_an_engine_spreads_between_the_side_walls(tmp_path, engine):
    """A LIGGGHTS or LAMMPS layer between the side walls (about 7 s each): every sphere stays
    between them, every sphere is accounted for."""
    if {"liggghts": find_liggghts, "lammps": find_lammps}[engine]() is None:
        pytest.skip(f"{engine} is not installed (bash .ci/install-engines.sh)")
    cfg = load_config(preset="tiny", overrides=[
        *_SMALL, "spread.n_frames=2", "spread.side_walls=true", f"engine={engine}",
        "output.contacts=false"])
    res = run_spread(cfg, out=tmp_path)
    layer = res.layers[0]
    assert layer.n_bed > 0 and layer.n_bed + layer.n_heap + layer.n_removed == layer.n_inserted
    for fr in read_dump(tmp_path / "layer01" / "frames.dump.gz", units="si"):
        _assert_between_walls(fr, W)


def test_a_run_folder_without_the_side_walls_key_resumes_and_side_walls_are_another_run(tmp_path):
    """A run folder whose configuration has no ``spread.side_walls`` (nor a PSD table) ran
    without them: the same configuration resumes it, side walls are another run."""
    from bedstruct.errors import ConfigError
    from bedstruct.workflows import RunLayout
    cfg = load_config(preset="tiny")
    RunLayout(tmp_path, cfg, workflow="spread").release()
    # at their defaults the keys are not in the folder's marker: as in a folder written by
    # a configuration without them
    d = json.loads((tmp_path / "run.json").read_text())
    assert "side_walls" not in d["config"]["spread"] and "diameters" not in d["config"]["psd"]
    assert d["config"]["spread"]["width"] == cfg["spread"]["width"]
    lay = RunLayout(tmp_path, cfg, workflow="spread")
    assert lay.resumed
    lay.release()
    walled = load_config(preset="tiny", overrides=["spread.side_walls=true"])
    with pytest.raises(ConfigError, match=r"`spread\.side_walls`: '\(missing\)' in the folder, "
                                          r"True now"):
        RunLayout(tmp_path, walled, workflow="spread")
