"""Ctrl-C during a run-library build on a Dask cluster keeps the runs finished and in flight."""

from __future__ import annotations

import json
import logging
import os
import signal
import threading
import time
from pathlib import Path

import pytest

distributed = pytest.importorskip("distributed")

from bedstruct.diagnose import (BASE_PARAMETERS, MeasurementSet, SurrogateSimulator,  # noqa: E402
                                measurement_from_dict)
from bedstruct.diagnose.run_design import design_points, design_spec  # noqa: E402
from bedstruct.diagnose.run_library import build_library  # noqa: E402

#: How long a run after the first takes, s: no run starts or ends for this long after the
#: interrupt, so the runs in flight are known when it comes.
SLOW = 1.5


def _one_angle():
    return MeasurementSet((measurement_from_dict({"name": "aor", "kind": "static_angle",
                                                  "role": "calibrate", "uncertainty": 0.5,
                                                  "value": 33.0}),))


class Marked:
    """The surrogate, writing ``<n>.json`` (its inputs) to ``marks`` as its ``n``-th call
    starts; the first call takes ``first`` s, the others ``rest`` s. With ``fail`` the
    first call waits for the second to start, then fails."""

    name = "marked-surrogate"

    def __init__(self, marks, first=0.0, rest=0.0, fail=False):
        self.design = _one_angle()
        self.marks, self.first, self.rest, self.fail = str(marks), first, rest, fail

    def library_identity(self):   # the same runs whatever they take
        return {"wraps": "surrogate"}

    def __call__(self, base, effects, seed):
        n = 0
        while True:   # the next call number (an exclusive create: the workers run together)
            try:
                fd = os.open(os.path.join(self.marks, f"{n}.json"),
                             os.O_CREAT | os.O_EXCL | os.O_WRONLY)
                break
            except FileExistsError:
                n += 1
        with os.fdopen(fd, "w") as fh:
            json.dump({"base": base, "effects": effects, "seed": int(seed)}, fh)
        if n == 0 and self.fail:
            deadline = time.time() + 30
            while len(os.listdir(self.marks)) < 2 and time.time() < deadline:
                time.sleep(0.01)
            time.sleep(self.first)
            raise ValueError("the first run failed")
        time.sleep(self.first if n == 0 else self.rest)
        return SurrogateSimulator(self.design)(base, effects, seed)


def _runs(folder: Path, pattern="*.json") -> set:
    """The inputs of the run (or mark) files of ``folder``."""
    out = set()
    for f in folder.glob(pattern):
        r = json.loads(f.read_text())
        out.add((json.dumps(r["base"], sort_keys=True), json.dumps(r["effects"], sort_keys=True),
                 r["seed"]))
    return out


class CtrlC:
    """Presses Ctrl-C (SIGINT to the main thread) once ``when()`` holds, unless stopped first."""

    def __init__(self, when, timeout=60.0):
        self.when, self.deadline = when, time.time() + timeout
        self.lock = threading.Lock()
        self.stopped = self.pressed = False
        self.thread = threading.Thread(target=self._watch, daemon=True)
        self.thread.start()

    def _watch(self):
        while time.time() < self.deadline:
            with self.lock:
                if self.stopped:
                    return
                if self.when():
                    self.pressed = True
                    signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)
                    return
            time.sleep(0.01)

    def stop(self):
        with self.lock:
            self.stopped = True
        self.thread.join()


@pytest.fixture
def client():
    """A client of a 2-worker cluster (threads of this process, one run at a time each),
    with Ctrl-C raising KeyboardInterrupt in the main thread."""
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("Ctrl-C reaches the main thread only")
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                      dashboard_address=None) as cluster, \
                distributed.Client(cluster) as c:
            yield c
    finally:
        signal.signal(signal.SIGINT, old)


def _interrupted_build(client, tmp_path, second_press=None):
    """A build on ``client`` interrupted once a run is saved and two more have started
    (one per worker, in flight for :data:`SLOW` s); ``second_press``: an event on which
    Ctrl-C is pressed again. The spec, the library folder and the marks folder."""
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=2, n_per_effect=2,
                       replicates=2)
    out, marks = tmp_path / "lib", tmp_path / "marks"
    marks.mkdir()
    presses = [CtrlC(lambda: len(list((out / "runs").glob("*.json"))) >= 1
                     and len(list(marks.iterdir())) >= 3)]
    if second_press is not None:
        presses.append(CtrlC(second_press.is_set))
    with pytest.raises(KeyboardInterrupt):
        try:
            build_library(Marked(marks, first=0.2, rest=SLOW), spec, out, scheduler=client,
                          progress=False)
        finally:
            for p in presses:
                p.stop()
    assert all(p.pressed for p in presses)
    return spec, out, marks


def test_ctrl_c_during_a_dask_build_saves_the_runs_finished_and_in_flight(client, tmp_path,
                                                                          caplog):
    with caplog.at_level("WARNING", logger="bedstruct.diagnose.run_library"):
        spec, out, marks = _interrupted_build(client, tmp_path)
    total = len(design_points(spec)) * spec.replicates
    started, saved = _runs(marks), _runs(out / "runs")
    # the run finished and the two in flight are saved; the runs not started were cancelled
    assert len(started) == 3 and saved == started
    assert "interrupted; nothing more is started. Waiting for the 2 run(s) in flight" \
        in caplog.text
    assert not (out / "build.lock").exists()
    # a second build runs only the runs left
    marks2 = tmp_path / "marks2"
    marks2.mkdir()
    lib = build_library(Marked(marks2), spec, out, scheduler=client, progress=False)
    assert lib.complete and lib.n_new == total - 3
    assert len(list(marks2.iterdir())) == total - 3 and not _runs(marks2) & saved
    # every run file as an uninterrupted build writes it
    whole = tmp_path / "whole"
    (tmp_path / "marks3").mkdir()
    build_library(Marked(tmp_path / "marks3"), spec, whole, progress=False)

    def record(f):
        return {k: v for k, v in json.loads(f.read_text()).items() if k not in ("wall_s", "cpu_s")}

    files = sorted(f.name for f in (whole / "runs").glob("*.json"))
    assert files == sorted(f.name for f in (out / "runs").glob("*.json"))
    assert all(record(whole / "runs" / n) == record(out / "runs" / n) for n in files)


def test_a_second_ctrl_c_stops_the_wait_and_cancels_the_runs_in_flight(client, tmp_path):
    waiting = threading.Event()

    class Waiting(logging.Handler):
        def emit(self, record):
            if "Waiting for the" in record.getMessage():
                waiting.set()

    logger = logging.getLogger("bedstruct.diagnose.run_library")
    handler = Waiting()
    logger.addHandler(handler)
    try:
        _, out, marks = _interrupted_build(client, tmp_path, second_press=waiting)
    finally:
        logger.removeHandler(handler)
    # the runs in flight were not waited for: only the one finished is saved
    assert len(list(marks.iterdir())) == 3 and len(_runs(out / "runs")) == 1
    scheduler = client.cluster.scheduler
    deadline = time.time() + 30
    while any(ts.state != "memory" for ts in scheduler.tasks.values()):   # the rest cancelled
        assert time.time() < deadline, "runs left on the cluster"
        time.sleep(0.05)
    assert len(list(marks.iterdir())) == 3   # nothing started after


def test_a_failed_run_on_dask_saves_the_runs_in_flight_and_is_raised(client, tmp_path, caplog):
    spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=2, n_per_effect=2,
                       replicates=2)
    out, marks = tmp_path / "lib", tmp_path / "marks"
    marks.mkdir()
    with caplog.at_level("WARNING", logger="bedstruct.diagnose.run_library"), \
            pytest.raises(ValueError, match="the first run failed"):
        build_library(Marked(marks, first=0.2, rest=SLOW, fail=True), spec, out,
                      scheduler=client, progress=False)
    failed, in_flight = (_runs(marks, n) for n in ("0.json", "1.json"))
    saved = _runs(out / "runs")
    # the run in flight (started before the failure, running SLOW s) was waited for
    assert in_flight <= saved and not failed & saved and saved <= _runs(marks)
    assert "a run failed (ValueError('the first run failed')); nothing more is started" \
        in caplog.text
    assert "failed (ValueError('the first run failed')); not saved" in caplog.text
    assert len(saved) < len(design_points(spec)) * spec.replicates
