"""How jobs run from Python: progress on the caller's thread, Ctrl-C, the GIL released, jobs in
several threads at once."""

import _thread
import concurrent.futures
import os
import signal
import threading
import time

import pytest

import lightstage as ls
from conftest import ENVMAP


def test_progress_callable(field_file):
    events = []
    caller = threading.get_ident()

    def progress(phase, done, total, item):
        events.append((phase, done, total, item, threading.get_ident()))

    ls.fit(field_file, progress=progress)
    assert events
    assert {e[4] for e in events} == {caller}  # Always on the thread that started the job.
    assert all(0 <= done <= total for _, done, total, _, _ in events)
    phases = {e[0] for e in events}
    # Every phase ends with done == total.
    for phase in phases:
        last = [e for e in events if e[0] == phase][-1]
        assert last[1] == last[2], last


class FakeBar:
    """What lightstage uses of a tqdm-like class."""
    bars = []

    def __init__(self, total, desc):
        self.total, self.desc, self.n, self.closed = total, desc, 0, False
        FakeBar.bars.append(self)

    def update(self, n):
        assert n > 0
        self.n += n

    def close(self):
        self.closed = True


def test_progress_bar_class(field_file):
    FakeBar.bars = []
    ls.relight(field_file, env=ENVMAP, progress=FakeBar)
    assert FakeBar.bars
    # One bar per phase, each closed; a phase may end by the next one starting, as in the CLI.
    assert len({bar.desc for bar in FakeBar.bars}) == len(FakeBar.bars)
    for bar in FakeBar.bars:
        assert bar.closed and 0 <= bar.n <= bar.total, (bar.desc, bar.n, bar.total)
    assert FakeBar.bars[-1].n == FakeBar.bars[-1].total


def test_progress_true_prints_a_bar(field_file, capsys):
    ls.normals(field_file, progress=True)
    assert "normals" in capsys.readouterr().err


def test_a_bad_progress_is_refused(field_file):
    with pytest.raises(TypeError):
        ls.normals(field_file, progress=42)


def test_an_exception_in_the_callable_stops_the_job(field_file, tmp_path):
    class Stop(Exception):
        pass

    def progress(phase, done, total, item):
        raise Stop(phase)

    with pytest.raises(Stop):
        ls.fit(field_file, out=tmp_path / "maps.exr", progress=progress)
    assert not (tmp_path / "maps.exr").exists()  # Stopped before writing.


@pytest.mark.parametrize("how", ["SIGINT", "interrupt_main"])
def test_ctrl_c_stops_a_job(field_file, tmp_path, how):
    senders = []

    def interrupt():
        if how == "SIGINT":
            os.kill(os.getpid(), signal.SIGINT)  # What Ctrl-C sends.
        else:
            _thread.interrupt_main()

    def progress(phase, done, total, item):
        # Once the job runs, Ctrl-C comes from another thread, as from the terminal.
        if not senders:
            senders.append(threading.Thread(target=interrupt))
            senders[0].start()

    with pytest.raises(KeyboardInterrupt):
        ls.fit(field_file, out=tmp_path / "maps.exr", memory="256K", progress=progress)
    senders[0].join()
    # The job ran and ended: another starts and finishes as usual.
    assert ls.normals(field_file).maps["normal"].shape == (40, 40, 3)


def test_the_gil_is_released(field_file):
    ticks = 0
    running = threading.Event()
    done = threading.Event()

    def count():
        nonlocal ticks
        running.set()
        while not done.is_set():
            ticks += 1
            time.sleep(0.001)

    counter = threading.Thread(target=count)
    counter.start()
    running.wait()
    before = ticks
    try:
        ls.fit(field_file)
    finally:
        done.set()
        counter.join()
    # The counter ran while the fit did (a held GIL would leave it no turn at all).
    assert ticks - before > 5


def test_jobs_in_two_threads(field_file):
    alone = ls.relight(field_file, env=ENVMAP, rotate=[0, 45])
    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        runs = list(pool.map(lambda _: ls.relight(field_file, env=ENVMAP, rotate=[0, 45]),
                             range(2)))
    for run in runs:
        assert run.images.keys() == alone.images.keys()
        for label, image in run.images.items():
            assert image.tobytes() == alone[label].tobytes()
    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        fits = list(pool.map(lambda _: ls.fit(field_file).maps["albedo"], range(2)))
    assert fits[0].tobytes() == fits[1].tobytes()


def test_ctrl_c_stops_a_capture_resumably(stage_file, tmp_path):
    frames = []

    def progress(phase, done, total, item):
        frames.append(done)
        if len(frames) == 5:
            raise KeyboardInterrupt  # As Ctrl-C during the capture.

    with pytest.raises(KeyboardInterrupt):
        ls.capture(stage_file, out=tmp_path / "s", progress=progress)
    # The capture stopped cleanly: the frames it saved are kept, and resume completes the rest.
    resumed = ls.capture(out=tmp_path / "s", resume=True)
    summary = resumed.summary
    assert not summary["already_complete"]
    assert summary["frames_present_before"] >= 5 and summary["frames_missing_before"] > 0
    assert summary["frames_captured"] == summary["frames_missing_before"]
