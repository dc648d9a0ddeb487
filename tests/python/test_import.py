"""import_set: a one-light-at-a-time set written here (an .lp file and its PNGs) as a field."""

import struct
import zlib

import numpy as np

import lightstage as ls


def write_png(path, rgb):
    """An 8-bit RGB PNG of an H x W x 3 uint8 array."""
    height, width, _ = rgb.shape
    raw = b"".join(b"\x00" + rgb[y].tobytes() for y in range(height))

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) +
                     chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def test_import_a_lambertian_plane(tmp_path):
    # A matte plane facing the camera (+Z) with albedo 0.8, lit from 6 directions: its linear
    # value under light l is 0.8 * cos(theta_l) = 0.8 * l_z (unit irradiance).
    dirs = np.array([[0, 0, 1], [0.5, 0, 0.8], [-0.5, 0.2, 0.7], [0, -0.6, 0.6],
                     [0.3, 0.3, 0.5], [-0.2, -0.4, 0.9]])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    lines = [str(len(dirs))]
    for i, d in enumerate(dirs):
        code = np.full((6, 8, 3), round(255 * 0.8 * d[2]), dtype=np.uint8)
        write_png(tmp_path / f"img{i}.png", code)
        lines.append(f"img{i}.png {d[0]:.6f} {d[1]:.6f} {d[2]:.6f}")
    (tmp_path / "set.lp").write_text("\n".join(lines) + "\n")

    imported = ls.import_set(tmp_path / "set.lp", out=tmp_path / "field.exr", linear=True,
                             storage="float")
    field = imported.field
    assert field.shape == (6, 8, 6, 3)
    np.testing.assert_allclose(field.lights.directions, dirs, atol=1e-5)
    values = field.values()
    expected = np.round(255 * 0.8 * dirs[:, 2]) / 255
    np.testing.assert_allclose(values, np.broadcast_to(expected[None, None, :, None], values.shape),
                               atol=1e-6)
    assert imported.summary["images"] == 6
