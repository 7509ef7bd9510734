"""What a run does with what it cannot use: runs of other code in its folder, piles that
cannot be measured, calibration points without a pile, powder in the air over the bed."""

import json

import numpy as np
import pytest

from bedstruct.errors import ConfigError
from bedstruct.workflows import RunLayout, calibrate_cohesion, load_config, repose, run_repose
from bedstruct.workflows.repose_measure import ReposeReplicate, combine_replicates

NAN = float("nan")


def _rep(seed, angle, note="", cohesion=3e3, stage=""):
    return ReposeReplicate(seed=seed, cohesion=cohesion, angle_deg=angle, angle_std_deg=0.5,
                           left_deg=angle, right_deg=angle, n_inserted=800, n_remaining=790,
                           n_fallen=10, pile_height=1e-3, wall_time=0.0, stage=stage, note=note)


@pytest.mark.parametrize("status", ["complete", "running"])
def test_a_run_of_other_code_is_refused(tmp_path, status):
    cfg = load_config(preset="tiny")
    lay = RunLayout(tmp_path, cfg, workflow="repose")
    if status == "complete":
        lay.write_results({"workflow": "repose"})
    lay.release()
    del lay
    marker = tmp_path / "run.json"
    d = json.loads(marker.read_text())
    from bedstruct import __version__
    assert d["code"]["bedstruct"] == __version__ and len(d["code"]["source"]) == 16
    d["code"] = {"bedstruct": "0.0.1", "source": "0123456789abcdef"}
    marker.write_text(json.dumps(d))
    with pytest.raises(ConfigError, match=r"other code \(bedstruct 0\.0\.1.*--overwrite"):
        RunLayout(tmp_path, cfg, workflow="repose")
    # a marker without the code (made before it was recorded) is other code too
    d.pop("code")
    marker.write_text(json.dumps(d))
    with pytest.raises(ConfigError, match="code not recorded"):
        RunLayout(tmp_path, cfg, workflow="repose")
    RunLayout(tmp_path, cfg, workflow="repose", overwrite=True)


def test_unmeasured_replicates_are_counted_and_explained():
    res = combine_replicates([_rep(1, 30.0), _rep(2, NAN, "no pile formed: 1 of 800 drained"),
                              _rep(3, NAN)], 3e3)
    assert res.angle_deg == 30.0 and res.n_measured == 1
    d = res.to_dict()
    assert d["n_measured"] == 1
    assert d["unmeasured"] == {"rep01": "no pile formed: 1 of 800 drained",
                               "rep02": "the pile could not be measured"}


def test_a_failing_run_marks_its_folder_failed(tmp_path, monkeypatch):
    def boom(cfg, *, seed, cohesion, layout=None, stage=""):
        raise RuntimeError("engine blew up")
    monkeypatch.setattr(repose, "repose_replicate", boom)
    with pytest.raises(RuntimeError):
        run_repose(load_config(preset="tiny"), out=tmp_path)
    d = json.loads((tmp_path / "run.json").read_text())
    assert d["status"] == "failed" and "engine blew up" in d["error"]


def test_an_interrupted_run_says_so_and_resumes(tmp_path, monkeypatch):
    calls = []

    def first_interrupted(cfg, *, seed, cohesion, layout=None, stage=""):
        calls.append(stage)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return _rep(seed, 30.0, cohesion=cohesion, stage=stage)
    monkeypatch.setattr(repose, "repose_replicate", first_interrupted)
    cfg = load_config(preset="tiny", overrides=["repose.replicates=2"])
    with pytest.raises(KeyboardInterrupt):
        run_repose(cfg, out=tmp_path)
    d = json.loads((tmp_path / "run.json").read_text())
    assert d["status"] == "interrupted" and d["error"] == "KeyboardInterrupt"
    # the finished replicate is kept: the rerun makes only the interrupted one
    res = run_repose(cfg, out=tmp_path)
    assert calls == ["rep00", "rep01", "rep01"] and res.n_measured == 2
    assert json.loads((tmp_path / "run.json").read_text())["status"] == "complete"


def test_a_calibration_without_any_pile_names_its_points(tmp_path, monkeypatch):
    def no_pile(cfg, *, seed, cohesion, layout=None, stage=""):
        return _rep(seed, NAN, "repose: only 5 particles remain in the box", cohesion, stage)
    monkeypatch.setattr(repose, "repose_replicate", no_pile)
    cfg = load_config(preset="tiny", overrides=["calibrate.cohesion_bracket=[1000.0, 2000.0]"])
    with pytest.raises(ConfigError) as e:
        calibrate_cohesion(cfg, out=tmp_path)
    msg = str(e.value)
    assert "k = 1000 J/m^3" in msg and "k = 2000 J/m^3" in msg
    assert str(tmp_path / "k1000") in msg and "only 5 particles remain" in msg
    assert json.loads((tmp_path / "run.json").read_text())["status"] == "failed"


def test_a_calibration_point_without_a_pile_is_recorded(tmp_path, monkeypatch):
    def model(cfg, *, seed, cohesion, layout=None, stage=""):
        if cohesion > 1.5e3:
            return _rep(seed, NAN, "no pile formed", cohesion, stage)
        return _rep(seed, 20.0 + 1e-3 * cohesion, "", cohesion, stage)
    monkeypatch.setattr(repose, "repose_replicate", model)
    cfg = load_config(preset="tiny", overrides=["calibrate.cohesion_bracket=[1000.0, 2000.0]"])
    res = calibrate_cohesion(cfg, out=tmp_path)
    bad = [p for p in res.curve if p.cohesion == 2000.0][0]
    assert np.isnan(bad.angle_deg) and "no pile formed" in bad.note
    assert not res.bracketed and res.cohesion == 1000.0


def test_the_bed_leaves_out_powder_in_the_air():
    from bedstruct import Frame
    from bedstruct.analysis import find_contacts
    from bedstruct.workflows.spread_measure import measure_layer
    cfg = load_config(preset="tiny", overrides=["spread.gaps=[4.5e-4]"])
    r, z_plat = 60e-6, -4.5e-4
    xs = np.arange(r, 2e-3 - r, 2 * r)
    ys = np.arange(r, 0.6e-3 - r, 2 * r)
    bed = np.array([[x, y, z_plat + r + 2 * r * k] for x in xs for y in ys for k in range(3)])
    flying = np.array([[0.8e-3 + 0.2e-3 * i, 0.3e-3, 2e-3] for i in range(4)])
    pos = np.vstack([bed, flying])
    fr = Frame(pos, np.full(len(pos), r), box=([0, 0, -1e-3], [2.5e-3, 0.6e-3, 3e-3]))
    layer, _, _ = measure_layer(fr, find_contacts(fr), cfg, index=1, z_plat=z_plat,
                                front0=0.5e-3, r_max=70e-6, pile=fr, dyn=[NAN], cn_series=[0.0],
                                blade_pos=[0.0], mid=[], n_inserted=len(pos), n_removed=0,
                                wall_time=0.0, segregation_values=(NAN, NAN))
    assert layer.n_bed == len(bed) and layer.n_heap == len(flying)
    assert layer.bed_top_m < 0.4e-3


@pytest.mark.slow
def test_a_cohesive_block_gives_no_pile_and_says_why(tmp_path):
    res = run_repose(load_config(preset="tiny", overrides=["contact.cohesion=1e5"]), out=tmp_path)
    assert res.n_measured == 0 and "no pile formed" in res.replicates[0].note
