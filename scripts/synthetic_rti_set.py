#!/usr/bin/env python3
"""A synthetic RTI set the size of a real dome's photographs, for measuring speed and memory.

A Lambertian sphere resting on a textured Lambertian plane, seen by an orthographic camera
looking down -Z, lit by 41 distant LEDs on a Fibonacci spiral 15-85 degrees above the plane; the
sphere casts its shadow on the plane. Writes WIDTH x HEIGHT 8-bit binary PPMs (sRGB-encoded) and
an `.lp` listing each image's light direction, as RTI sets are.

  python3 scripts/synthetic_rti_set.py 4608 2592 OUT   # the 12-megapixel class (~1.5 GB)
  lightstage import OUT/set.lp --out big.exr
"""
import argparse
import os

import numpy as np

LEDS = 41


def led_directions():
    dirs = []
    for i in range(LEDS):
        z = np.sin(np.radians(15 + 70 * (i + 0.5) / LEDS))
        phi = i * np.pi * (3 - np.sqrt(5))
        r = np.sqrt(1 - z * z)
        dirs.append((r * np.cos(phi), r * np.sin(phi), z))
    return np.array(dirs)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("width", type=int)
    parser.add_argument("height", type=int)
    parser.add_argument("out")
    args = parser.parse_args()
    w, h = args.width, args.height
    os.makedirs(args.out, exist_ok=True)
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
    # The sphere: radius r pixels, resting on the plane z = 0 at the image's centre.
    r = h * 0.3
    px, py = xs - w * 0.5, -(ys - h * 0.5)
    nx, ny = px / r, py / r
    on_sphere = nx * nx + ny * ny < 1
    nz = np.sqrt(np.clip(1 - nx * nx - ny * ny, 0, 1))
    texture = 0.5 + 0.25 * np.sin(xs / 37.0) * np.sin(ys / 53.0) + 0.1 * ((xs // 64 + ys // 64) % 2)
    plane_albedo = np.stack([texture * 0.9, texture * 0.8, texture * 0.7], -1)
    sphere_albedo = np.array([0.8, 0.5, 0.3], np.float32)
    lines = [str(LEDS)]
    for i, d in enumerate(led_directions()):
        name = f"img{i:03d}.ppm"
        lines.append(f"{name} {d[0]:.6f} {d[1]:.6f} {d[2]:.6f}")
        # A plane point (px, py, 0) is shadowed where its ray toward d meets the sphere (centre
        # (0, 0, r)): from the centre, o = (px, py, -r): b = o.d < 0 and b^2 > |o|^2 - r^2.
        b = px * d[0] + py * d[1] - r * d[2]
        shadowed = (b < 0) & (b * b > px * px + py * py)
        plane = plane_albedo * (d[2] * ~shadowed)[..., None]
        sphere = sphere_albedo * np.clip(nx * d[0] + ny * d[1] + nz * d[2], 0, None)[..., None]
        linear = np.where(on_sphere[..., None], sphere, plane) * 0.8
        codes = (np.clip(linear, 0, 1) ** (1 / 2.2) * 255 + 0.5).astype(np.uint8)
        with open(os.path.join(args.out, name), "wb") as f:
            f.write(b"P6\n%d %d\n255\n" % (w, h))
            f.write(codes.tobytes())
    with open(os.path.join(args.out, "set.lp"), "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
