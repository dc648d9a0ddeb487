"""The library's errors: the message, and the file and field it names.

lightstage's messages name what is wrong first, as ``FILE: FIELD: what was expected`` (for
example ``maps.exr: channel 'model': expected an integer in 0..4 at (3, 7), got 9``) or, for an
option, ``JOB: --OPTION: what``; ``file`` and ``field`` are those parts (None where the message
names none).
"""

import os

_JOBS = ("capture", "build", "relight", "fit", "normals", "compress", "render", "import",
         "export openlime")
_SUFFIXES = (".exr", ".json", ".png", ".jpg", ".hdr", ".lp", ".ptm", ".rti", ".txt", ".pca")


def _looks_like_file(text):
    return ("/" in text or text.lower().endswith(_SUFFIXES) or os.path.exists(text)) \
        and "\n" not in text


def _looks_like_field(text):
    # An option (--env), a dotted key (camera.bracket), a channel ('model') or a short name.
    return bool(text) and len(text) <= 60 and (text.startswith("channel ") or " " not in text)


def _split(message):
    parts = message.split(": ")
    file = field = None
    if len(parts) > 1 and parts[0] in _JOBS:
        parts = parts[1:]
    if len(parts) > 1 and _looks_like_file(parts[0]):
        file, parts = parts[0], parts[1:]
    if len(parts) > 1 and parts[0].startswith("--"):
        field = parts[0].split()[0]  # "--memory '12 parsecs'": the option, then what was given.
    elif len(parts) > 1 and _looks_like_field(parts[0]):
        field = parts[0]
    return file, field


class Error(Exception):
    """A lightstage error. ``message``: the library's sentence; ``file``, ``field``: what it names."""

    def __init__(self, message, file=None, field=None):
        super().__init__(message)
        named_file, named_field = _split(message)
        self.message = message
        self.file = file if file is not None else named_file
        self.field = field if field is not None else named_field

    def __str__(self):
        return self.message


class InputError(Error, ValueError):
    """Bad input: an option, a file's content. The CLI exits with 2 for these."""


class StorageError(Error, OSError):
    """A file or folder that could not be written or read (disk full, permissions, missing)."""

    def __init__(self, message, file=None, field=None, errno=None):
        Error.__init__(self, message, file, field)
        self.errno = errno
        self.filename = self.file


class HardwareError(Error, RuntimeError):
    """A device (camera, LED controller) that failed. The CLI exits with 3 for these."""
