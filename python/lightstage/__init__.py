"""lightstage from Python: reflectance fields as NumPy arrays, and the command line's jobs.

    import lightstage as ls
    f = ls.Field.open("field.exr")
    relit = ls.relight(f, env="data/envmaps/sky_sun.exr", rotate=[0, 90])
    maps = ls.fit(f).maps          # normal, albedo, model, flags, ... as arrays

Every job takes its options by keyword, as the CLI's flags (``memory="512M"`` for ``--memory
512M``), refuses bad ones with the CLI's messages (InputError, a ValueError), releases the GIL
while it works, reports progress to ``progress=`` (True: a bar; a callable (phase, done, total,
item); a tqdm-like class) and stops on Ctrl-C (KeyboardInterrupt). See docs/python.md.
"""

from ._errors import Error, HardwareError, InputError, StorageError
from ._lightstage import (Buffer, Field, FieldNoise, Lights, build, capture, compress, fit,
                          import_set, normals, read_image, relight, render)
from ._results import (Built, Captured, Compressed, Fitted, Imported, Normals, Relit,
                       Rendered)

__all__ = [
    "Buffer", "Built", "Captured", "Compressed", "Error", "Field", "FieldNoise", "Fitted",
    "HardwareError", "Imported", "InputError", "Lights", "Normals", "Relit", "Rendered",
    "StorageError", "build", "capture", "compress", "fit", "import_set", "normals", "read_image", "relight",
    "render",
]
