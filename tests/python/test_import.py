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


def test_import_takes_the_lights_directions_from_a_mirror_sphere(tmp_path):
    # One mirror sphere (centre (32, 30), radius 20 px) in every image, its highlight where an
    # orthographic camera sees it mirror the light: normal n = (view + l) / |view + l|, at
    # (cx + r n_x, cy - r n_y). The .lp lists directions 5 degrees off: the sphere's replace them.
    dirs = np.array([[0, 0, 1], [0.5, 0, 0.8], [-0.5, 0.2, 0.7], [0, -0.6, 0.6],
                     [0.3, 0.3, 0.5], [-0.2, -0.4, 0.9]])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    cx, cy, radius = 32.0, 30.0, 20.0
    ys, xs = np.mgrid[0:60, 0:64] + 0.5
    lines = [str(len(dirs))]
    for i, d in enumerate(dirs):
        n = (d + [0, 0, 1]) / np.linalg.norm(d + [0, 0, 1])
        hx, hy = cx + radius * n[0], cy - radius * n[1]
        image = np.where(np.hypot(xs - cx, ys - cy) < radius, 5.0, 40.0)
        image += 250 * np.exp(-((xs - hx) ** 2 + (ys - hy) ** 2) / (2 * 1.2 ** 2))
        code = np.repeat(np.clip(np.round(image), 0, 255).astype(np.uint8)[:, :, None], 3, axis=2)
        write_png(tmp_path / f"img{i}.png", code)
        listed = d + [0.087, 0, 0]
        listed /= np.linalg.norm(listed)
        lines.append(f"img{i}.png {listed[0]:.6f} {listed[1]:.6f} {listed[2]:.6f}")
    (tmp_path / "set.lp").write_text("\n".join(lines) + "\n")

    imported = ls.import_set(tmp_path / "set.lp", out=tmp_path / "field.exr", linear=True,
                             circles=[(cx, cy, radius)])
    assert "6 of 6 lights found on 1 sphere: directions only" in imported.summary["light_placement"]
    found = imported.field.lights.directions
    cos = np.clip(np.sum(found * dirs, axis=1), -1, 1)
    assert np.degrees(np.arccos(cos)).max() < 0.5
