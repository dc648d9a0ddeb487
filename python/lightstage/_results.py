"""What the jobs return: their outputs (arrays, fields, files) and the job's summary as a dict."""

from dataclasses import dataclass, field
from os import PathLike
from typing import Any, Dict, List, Optional


@dataclass
class Captured:
    """A captured session folder (build it with lightstage.build)."""
    session: PathLike
    summary: Dict[str, Any] = field(default_factory=dict)


@dataclass
class Built:
    """The fields a build wrote (one, or one per time step), opened."""
    fields: List[Any]
    summary: Dict[str, Any] = field(default_factory=dict)


@dataclass
class Imported:
    """The field an import wrote, opened."""
    field: Any
    summary: Dict[str, Any] = field(default_factory=dict)


@dataclass
class Relit:
    """Relit images (H x W x 3 float32, linear) by name, their files' names: the map's, with the
    rotation when several were asked for ("sky_sun_rot090"). ``out``: the folder holding their EXR and PNG files and
    the contact sheet (None when none was asked for: the files were temporary)."""
    images: Dict[str, Any]
    out: Optional[PathLike] = None
    summary: Dict[str, Any] = field(default_factory=dict)

    def __getitem__(self, label):
        return self.images[label]


@dataclass
class _Maps:
    """Per-pixel maps by name; ``out``: their file (None: it was temporary)."""
    maps: Dict[str, Any]
    out: Optional[PathLike] = None
    summary: Dict[str, Any] = field(default_factory=dict)

    def __getitem__(self, name):
        return self.maps[name]


class Fitted(_Maps):
    """Model maps by name: normal, albedo (H x W x 3); sigma, ks, roughness, model (FitModel
    codes), confidence, residual, flags, material, material_weight, material2, material2_weight
    (H x W). ``out``: the maps file (None: it was temporary)."""


class Normals(_Maps):
    """Photometric-stereo normals: normal, albedo (H x W x 3), confidence, flags (H x W)."""


@dataclass
class Compressed:
    """The compact file written."""
    out: PathLike
    summary: Dict[str, Any] = field(default_factory=dict)


@dataclass
class Rendered:
    """A compact file relit: the image (H x W x 3 float32, linear)."""
    image: Any
    out: Optional[PathLike] = None
    summary: Dict[str, Any] = field(default_factory=dict)
