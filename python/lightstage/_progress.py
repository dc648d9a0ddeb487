"""What ``progress=`` may be, made into the one callable the jobs report to:
(phase, done, total, item), called on the thread that started the job."""

import sys


class _Bars:
    """One bar per phase from a tqdm-like class: cls(total=..., desc=...) with update(n), close()."""

    def __init__(self, cls):
        self._cls = cls
        self._phase = None
        self._bar = None
        self._done = 0

    def __call__(self, phase, done, total, item):
        if self._bar is None or phase != self._phase:
            self.close()
            self._bar = self._cls(total=total, desc=phase)
            self._phase, self._done = phase, 0
        if total != getattr(self._bar, "total", total):
            self._bar.total = total  # A phase that learns its size as it goes.
        if done > self._done:
            self._bar.update(done - self._done)
            self._done = done
        if done >= total:
            self.close()

    def close(self):
        if self._bar is not None:
            self._bar.close()
        self._bar, self._phase = None, None


class _TextBar:
    """A line on stderr per phase, redrawn in place: "fit (rows) [#####     ] 120/256"."""

    def __init__(self, stream=None):
        self._stream = stream or sys.stderr

    def __call__(self, phase, done, total, item):
        width = 30
        filled = width * done // total if total > 0 else width
        end = "\n" if done >= total else ""
        self._stream.write(f"\r{phase} [{'#' * filled}{' ' * (width - filled)}] {done}/{total}{end}")
        self._stream.flush()


def adapt(progress):
    """None or False: no reports. True: a tqdm bar when tqdm is installed, else a line on stderr.
    A class (tqdm.tqdm or alike): one bar of it per phase. A callable: called as
    progress(phase, done, total, item)."""
    if progress is None or progress is False:
        return None
    if progress is True:
        try:
            from tqdm.auto import tqdm  # noqa: PLC0415 (optional)
        except ImportError:
            return _TextBar()
        return _Bars(tqdm)
    if isinstance(progress, type):
        return _Bars(progress)
    if callable(progress):
        return progress
    raise TypeError("progress: expected None, True, a callable (phase, done, total, item) or a "
                    "tqdm-like class, got " + repr(progress))
