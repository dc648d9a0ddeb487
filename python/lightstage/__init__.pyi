"""lightstage: reflectance fields as NumPy arrays, and the command line's jobs.

Every job's options are the CLI's flags by keyword (``--coverage-deg`` is ``coverage_deg``); the
docstrings below are the flags' help texts (``lightstage CMD --help``). Every job releases the GIL
while it works, reports to ``progress`` (None; True: a bar; a callable (phase, done, total, item);
a tqdm-like class) and stops on Ctrl-C with KeyboardInterrupt.
"""

from os import PathLike
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Type, Union

import numpy as np
import numpy.typing as npt

from ._errors import Error as Error
from ._errors import HardwareError as HardwareError
from ._errors import InputError as InputError
from ._errors import StorageError as StorageError
from ._results import Built as Built
from ._results import Captured as Captured
from ._results import Compressed as Compressed
from ._results import Fitted as Fitted
from ._results import Imported as Imported
from ._results import Normals as Normals
from ._results import Relit as Relit
from ._results import Rendered as Rendered

_Path = Union[str, PathLike]
_FieldLike = Union[_Path, "Field"]
_Progress = Union[None, bool, Callable[[str, int, int, str], Any], Type[Any]]
_Memory = Union[None, str, int]
_F32 = npt.NDArray[np.float32]

class Buffer:
    """Memory of the library (a field's values, an image, model maps) that NumPy arrays view
    without copying: the base of those arrays."""
    @property
    def writable(self) -> bool:
        """Whether arrays over it may be written (writes are seen by the library)."""
    @property
    def what(self) -> str:
        """What the memory holds."""

class FieldNoise:
    """Measurement noise of a field's values: variance(v) = read_variance +
    shot_variance_per_unit * max(v, 0)."""
    read_variance: float
    shot_variance_per_unit: float
    measured: bool
    """False when nobody estimated it (imports, older files)."""
    method: str
    """How it was estimated."""

class Lights:
    """A field's lights, as arrays (copies: a few values per light), in the order of the field's
    light axis."""
    def __len__(self) -> int: ...
    @property
    def ids(self) -> npt.NDArray[np.int32]:
        """LED ids (L,)."""
    @property
    def directions(self) -> npt.NDArray[np.float64]:
        """Unit directions toward each LED, stage frame (+Y up, camera on +Z) (L x 3)."""
    @property
    def positions(self) -> npt.NDArray[np.float64]:
        """Near LEDs: positions in metres, stage frame; NaN rows for distant LEDs (L x 3)."""
    @property
    def valid(self) -> npt.NDArray[np.bool_]:
        """False for an LED found dead or missing: its samples are zero, not data (L,)."""
    @property
    def saturates_at(self) -> _F32:
        """Per LED and colour, the value of a sample clipped in every exposure (inf: never)."""
    @property
    def colours(self) -> npt.NDArray[np.float64]:
        """Each light's RGB colour in field units (L x 3): ones, since a field is stored per unit of
        each LED's calibrated irradiance and colour (build divides by them; an imported set is taken
        as white lights)."""

class Field:
    """A reflectance field file (OpenEXR, 'lightstage build' or 'import'): R(x, l), pixel x's
    linear value under LED l per unit of its irradiance."""
    @staticmethod
    def open(path: _Path) -> Field:
        """Opens a field file: reads its header (lights, noise, size), no values."""
    @property
    def path(self) -> PathLike: ...
    @property
    def shape(self) -> Tuple[int, int, int, int]:
        """(height, width, lights, 3): the shape of values()."""
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def lights(self) -> Lights:
        """The LEDs: ids, directions, positions (near LEDs), validity, saturation ceilings."""
    @property
    def noise(self) -> FieldNoise:
        """The measurement noise the build estimated."""
    @property
    def scene_time_s(self) -> float:
        """Scene time of the capture (time-varying sessions)."""
    @property
    def storage(self) -> str:
        """How the file holds the values ("half" or "float"; read as float32 either way)."""
    def rows(self, y0: int, y1: int) -> _F32:
        """Rows [y0, y1) as a float32 array (y1 - y0) x W x L x 3, read from the file without the
        other rows into a new buffer of the library's (the array's base; writable, a copy of the
        file's values)."""
    def values(self) -> _F32:
        """The whole field as a float32 array H x W x L x 3 (a small field: it must fit in
        memory). Read once; every call returns a view of the same memory, no copy, and writes
        through it are seen by save()."""
    def save_rows(self, path: _Path, y0: int, y1: int, storage: str = "auto") -> None:
        """Rows [y0, y1) as a field file of their own (read without the other rows): a band that
        another process or Dask worker can fit or relight. Refused for a field with near LEDs
        (their directions depend on the whole frame)."""
    def save(self, path: _Path, storage: str = "auto") -> None:
        """Writes the field as values() holds it (with any writes made through it) to a new field
        file. storage: auto | half | float, as 'lightstage build --storage'."""

def read_image(path: _Path) -> Tuple[_F32, List[str]]:
    """An image file as lightstage reads it (EXR, HDR, PNG, JPEG; linear float32): (H x W x C
    array over the library's image, the channel names in its order)."""

def capture(stage: Optional[_Path] = None, scene: Optional[_Path] = None, *, out: _Path,
            resume: bool = False, seed: int = 1, verify_frames: bool = True,
            exposures_from: Optional[_Path] = None, progress: _Progress = None) -> Captured:
    """Capture a one-light-at-a-time session: each LED on, its exposure bracket, off; dark frames;
    over the plan's time steps. Every frame is saved as it arrives; Ctrl-C stops cleanly (all LEDs
    off) and resume=True completes only what is missing.

    stage: Stage file (JSON: LEDs, camera, plan). Default: the built-in ~150-LED dome.
    scene: Scene file for the simulated stage (JSON). Default: the built-in demo scene.
    out: New session directory to create. With resume=True (--resume): the existing session
        directory to complete.
    seed: Noise seed of the simulated camera.
    verify_frames: False (--no-frame-checks): Save frames unchecked. By default each frame is
        checked on arrival (dark frames dark, a bracket's frames consistent with each other) and
        a bad one shot again; turn this off only for a camera whose frames do not follow the
        LEDs, such as Aravis' test-pattern Fake_1.
    exposures_from: An earlier session of the same stage and scene: each LED is shot only at the
        bracket steps that were the best exposure of its pixels there (fewer frames, the same
        field within its noise).
    """

def build(session: _Path, *, out: _Path, time_step: int = 0, all_time_steps: bool = False,
          memory: _Memory = None, storage: str = "auto", correct_drift: bool = False,
          progress: _Progress = None) -> Built:
    """Build the reflectance field of a session: dark subtraction, HDR merge through the camera
    response, division by each LED's calibrated irradiance and colour. Writes an OpenEXR with one
    channel per LED and colour (led042.R, ...).

    out: Field file to write (.exr); with --all-time-steps, the directory to write
        field_t000.exr, field_t001.exr, ... into.
    time_step: Time step to build (time-varying sessions).
    all_time_steps: Build one field per time step into the --out directory.
    memory: Build: the field's values and the LEDs merged in flight (a quarter of it); a larger
        field is built in bands, each LED's image spilled to a file beside out that needs the
        field's size free. SIZE: bytes, or with K, M, G, T (powers of 1024: 512M, 2G, 1.5GiB).
    storage: How the file holds the values: half floats (half the disk and the reading) where the
        field relit from them stays within 1e-3 of the floats and their rounding within 0.25
        sigma of the field's measured noise, else floats (auto); or always half or float.
        Recorded in the file (lightstage:storage).
    correct_drift: Divide each LED's image by the dome's output drift while it was shot, measured
        on the stage plan's reference LED (plan.reference_led, shot again every
        plan.reference_every LEDs). Drift beyond 0.5% is reported either way.
    """

def relight(field: Optional[_FieldLike] = None, *, env: Union[None, _Path, Sequence[_Path]] = None,
            rotate: Union[float, Sequence[float]] = 0.0, models: Optional[_Path] = None,
            temporal: Optional[_Path] = None, time: Optional[float] = None,
            edits: Optional[_Path] = None, light: Optional[Sequence[float]] = None,
            exposure: Optional[float] = None, coverage_deg: float = 0.0,
            bright_sources: bool = True, source_geometry: bool = True,
            source_pixels: int = 262144, memory: _Memory = None, directions: int = 64,
            out: Optional[_Path] = None, progress: _Progress = None) -> Relit:
    """Relight a reflectance field under lat-long HDR environment maps (.exr, .hdr): each LED
    stands for its spherical Voronoi cell of directions, I = sum_l R_l E_l. Or, with models,
    render the per-pixel BRDF models of 'lightstage fit' (edited with edits) under the maps.
    Returns the images as arrays; with out, also writes NAME.exr (linear) and NAME.png
    (tone-mapped preview) per map and rotation, and contact_sheet.png, as the CLI does.

    field: Reflectance field (.exr from 'lightstage build', or a Field); optional with models.
    env: Environment map(s), lat-long .exr or .hdr.
    rotate: Rotation(s) of the map about the vertical axis, degrees.
    models: Render fitted model maps (.exr from 'lightstage fit') instead of the field. The models
        have no shadows; pixels the fit flagged are black. With a field too, flagged pixels come
        from the field relit under the same map, and the models get only the light the dome
        covers, as the field does.
    temporal: Temporal maps from 'lightstage fit --time', rendered at time (with edits: a time
        edit file, see relight/time/temporal_render.h).
    time: With --temporal: scene time in seconds (any time; outside the captured steps it is
        flagged).
    edits: Edit file (JSON: selections by model or mask, albedo tint, roughness / specular /
        sigma scales, model swaps) applied to models before rendering.
    light: With --models: also render under one distant light from direction X Y Z (stage frame,
        toward the light) of unit irradiance, as light.exr/png.
    exposure: Preview exposure in stops (default: automatic per image).
    coverage_deg: Dome coverage radius around each LED, degrees (0: automatic).
    bright_sources: False (--no-bright-sources): relight a map's sun or small lamp by the LED
        cells too, as one LED cell's light each (shadows at the LEDs' directions), instead of
        rendering it at its true direction with moving shadows.
    source_geometry: False (--no-source-geometry): cast the bright sources' shadows by the flows
        between the LEDs' shadows alone, without the scene's shape recovered from them.
    source_pixels: Fields: a field of more pixels has its bright sources (normals, shape, the
        LEDs' shadows) made on it reduced to about this many, each pixel the mean of a block, and
        brought back to its size by the detail of the LEDs around each source. 0: at the field's
        size.
    memory: Relight: what rendering bright sources may hold (the images of the LEDs around them,
        at source_pixels); over it they are relit by the LED cells, with a note.
    directions: With --models: the map is integrated on a lat-long grid of N x N/2 directions.
    out: Output directory. None: the files are temporary, only the arrays are returned.
    """

def fit(field: _FieldLike, *, out: Optional[_Path] = None, phong: bool = False,
        dim_samples: bool = False, method: str = "robust", materials: str = "basis",
        memory: _Memory = None, progress: _Progress = None) -> Fitted:
    """Fit a BRDF model per pixel of a reflectance field: photometric-stereo normals, then
    Lambert, Oren-Nayar and Lambert + Torrance-Sparrow (and Lambert + Phong with phong), the
    model chosen by BIC. Returns the maps as arrays (normal, albedo, sigma, ks, roughness, model,
    confidence, residual, flags, material ids and weights); with out, writes MAPS.exr and a PNG
    preview per map beside it, as the CLI does.

    out: Model maps to write (.exr). None: a temporary file.
    phong: Also fit Lambert + Phong (for comparison).
    dim_samples: Fit each pixel again with its samples under the shadow threshold that its first
        fit predicts dim: for a dark or underexposed capture; slower.
    method: Photometric-stereo normals: robust (trimmed start + Tukey IRLS, ignores highlights)
        or ls (weighted least squares).
    materials: basis: cluster the per-pixel fits into the scene's few materials, fit each material
        on all of its pixels, and give each pixel the weights of one or two materials (its own
        fit kept where no material explains it); per-pixel: each pixel chooses its model alone.
    memory: Fit: the band of the field fitted at once (read twice with basis materials).
    """

def normals(field: _FieldLike, *, out: Optional[_Path] = None, method: str = "robust",
            memory: _Memory = None, progress: _Progress = None) -> Normals:
    """Photometric-stereo normals alone (no BRDF fit): normal, Lambertian albedo, confidence and
    flags per pixel; read in bands within memory.

    method: robust: iteratively reweighted, shadows and highlights left out; ls: least squares
        over the lit samples.
    memory: Normals: the band of the field read at once.
    """

def import_set(source: _Path, *, out: _Path, linear: bool = False, srgb: bool = False,
               gamma: Optional[float] = None, max_size: int = 0, drop_saturated: bool = False,
               keep_all: bool = False, circles: Sequence[Tuple[float, float, float]] = (),
               sphere_radius: float = 0.0, focal_length_px: float = 0.0,
               stage: Optional[_Path] = None, time: float = 0.0, storage: str = "auto",
               memory: _Memory = None, progress: _Progress = None) -> Imported:
    """Import an existing one-light-at-a-time photo set as a reflectance field: an RTI set
    described by an .lp file (N, then 'image x y z' per line) or a DiLiGenT photometric-stereo
    folder. Undoes the transfer curve (default: sRGB for .lp sets, linear for DiLiGenT), divides
    by each light's intensity, and writes the field plus FIELD.preview.png.

    out: Field file to write (.exr)
    linear: The images are linear already.
    srgb: Undo the sRGB curve (default for .lp sets).
    gamma: Undo a plain gamma curve: linear = code^G (G in (0, 10]).
    max_size: Downsize (area averaging) so that the larger side is at most N pixels.
    drop_saturated: Write saturated samples (maximum code) as 0, so fits leave them out as
        shadowed; default: keep them as lower bounds.
    keep_all: Keep every image: by default each is checked against what the others predict at
        its light, and those that disagree (shifted, another light's, black) are left out and
        listed.
    circles: A mirror sphere in every image: cx,cy,r in the images' pixels (x right, y down,
        pixel centres at +0.5), one (cx, cy, r) per sphere. The lights are placed from their
        highlights: one sphere gives directions, two give positions (near lights);
        summary["light_placement"] says what was found.
    sphere_radius: The spheres' radius in metres, for light positions in metres (0: a nominal
        scale).
    focal_length_px: With --circle: the camera's focal length in pixels of the images (a
        pinhole camera looking straight down; needs sphere_radius); 0: orthographic.
    stage: A calibrated stage file whose LEDs are the set's lights, in order: their directions,
        positions and irradiance replace what the set lists; its camera gives the view.
    time: Scene time of the set in seconds (default 0)
    storage: How the field file holds the values: half floats where the field relit from them
        stays within 1e-3 of the floats, else floats (auto); or always half or float.
    memory: Import: the field's values; a larger field is written in bands.
    """

def compress(input: _FieldLike, *, out: _Path, format: str = "pca", rank: Union[str, int] = "auto",
             tile: int = 0, gain: float = 0.0, encoding: str = "", memory: _Memory = None,
             progress: _Progress = None) -> Compressed:
    """Writes a compact representation of a field (EXR, or an .lp capture imported directly):
    .ptm (PTM_1.2 RGB/LRGB), .rti (HSH) or the lightstage PCA format.

    format: pca | ptm | ptm-lrgb | hsh2 | hsh3 | hsh4.
    rank: PCA rank: a number; auto (the LEDs' images to the noise floor: what a map's sun and
        small sources are rendered from); or held-out (the smallest within 0.25 dB of the best
        on held-out LEDs: the best relighting between the LEDs per byte). Never a file larger
        than the input.
    tile: PCA tile size in pixels (0: one global basis).
    gain: RTI files: display units (white = 1) per field unit; 0: the brightest sample is white.
    encoding: RTI files: srgb (the sRGB codes of the field, fitted as such: what RTIViewer,
        relight and OpenLIME show) or linear (.rti only, for lightstage's own use).
    memory: Compress: the band of the field read at once (twice for PCA).
    """

def render(input: _Path, *, light: Optional[Sequence[float]] = None, env: Optional[_Path] = None,
           rotate: float = 0.0, bright_sources: bool = True, out: Optional[_Path] = None,
           progress: _Progress = None) -> Rendered:
    """Relights a compact file (.ptm, .rti, the lightstage PCA format, or an OpenLIME folder)
    under one distant light or an environment map: a linear image in field units (and, with out,
    the EXR and a PNG preview).

    light: X Y Z: direction toward the light, stage frame (+Y up, camera on +Z), unit irradiance
        at normal incidence.
    env: Environment map (EXR/HDR) instead of --light.
    rotate: Rotation of the map about +Y, degrees.
    bright_sources: False (--no-bright-sources): A PCA under a map with a sun or small lamp:
        relight it by the LED cells too instead of rendering it at its true direction with moving
        shadows.
    out: Output image (.exr; a .png preview beside it). None: only the array is returned.
    """
