#!/usr/bin/env python3
"""Renders a sphere covered with a .nbtf material, in numpy: camera rays, the sphere's
shading frame, the decoder as the BSDF, one distant light (docs/python.md).

    PYTHONPATH=build/python python3 examples/python/render_sphere.py material.nbtf -o sphere.png

Writes PNG (with matplotlib installed; a .ppm name writes PPM, which needs nothing). BTF
values include the light's cosine, as measured stacks do, so the light term is
value x irradiance with no cosine of its own (the convention of `nbtf render`).
"""
import argparse
import os
import sys

import numpy as np

import nbtf


def normalize(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def render(material, size=256, light_dir=(0.5, 0.6, 0.8), tiling=2.0, sun=3.0, fov_deg=35.0):
    # Camera at +z looking at the unit sphere at the origin, y up.
    eye = np.array([0.0, 0.0, 3.5])
    half = np.tan(np.radians(fov_deg) / 2)
    px = (np.arange(size) + 0.5) / size * 2 - 1
    sx, sy = np.meshgrid(px * half, -px * half)  # rows top to bottom
    dirs = normalize(np.stack([sx, sy, -np.ones_like(sx)], axis=-1))

    # Ray-sphere intersection: |eye + t d|^2 = 1.
    b = dirs @ eye
    disc = b * b - (eye @ eye - 1)
    hit = disc > 0
    t = -b - np.sqrt(np.where(hit, disc, 0))
    p = eye + t[..., None] * dirs  # hit points = normals on the unit sphere
    n = p

    # Texture coordinates and the shading frame: u around the y axis, v from the top.
    phi = np.arctan2(p[..., 2], p[..., 0])
    theta = np.arccos(np.clip(p[..., 1], -1, 1))
    uv = np.stack([tiling * phi / (2 * np.pi), tiling * theta / (2 * np.pi)], axis=-1)
    tangent = normalize(np.stack([-np.sin(phi), np.zeros_like(phi), np.cos(phi)], axis=-1) + 1e-12)  # along u
    bitangent = np.cross(n, tangent)

    def local(w):  # world direction(s) -> the local frame (x = tangent, y = bitangent, z = normal)
        return np.stack([(w * tangent).sum(-1), (w * bitangent).sum(-1), (w * n).sum(-1)], axis=-1)

    light = local(np.broadcast_to(normalize(np.asarray(light_dir, float)), p.shape))
    view = local(-dirs)
    lit = hit & (light[..., 2] > 0) & (view[..., 2] > 0)

    image = np.zeros((size, size, 3), np.float32)
    # One batched query for every lit pixel: the decoder is the BSDF.
    rgb = material.query(uv=uv[lit], light=light[lit], view=view[lit])
    image[lit] = np.maximum(rgb, 0) * sun
    return image


def to_srgb8(linear):
    c = np.clip(linear, 0, 1)
    srgb = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)
    return (srgb * 255 + 0.5).astype(np.uint8)


def write_image(path, linear):
    pixels = to_srgb8(linear)
    if path.lower().endswith(".ppm"):
        h, w, _ = pixels.shape
        with open(path, "wb") as f:
            f.write(b"P6\n%d %d\n255\n" % (w, h) + pixels.tobytes())
        return
    try:
        import matplotlib.pyplot as plt
    except ImportError:
        sys.exit(f"render_sphere: writing {path} needs matplotlib; give a .ppm name instead")
    plt.imsave(path, pixels)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("material", help=".nbtf file")
    parser.add_argument("-o", "--output", default="sphere.png", help="image to write (.png or .ppm)")
    parser.add_argument("--size", type=int, default=256, help="image width and height in pixels")
    parser.add_argument("--tiling", type=float, default=2.0, help="texture copies around the sphere")
    parser.add_argument("--light", default="0.5,0.6,0.8", help="direction to the light, x,y,z in the world")
    args = parser.parse_args()
    light = tuple(float(v) for v in args.light.split(","))
    with nbtf.open(args.material) as m:
        image = render(m, size=args.size, light_dir=light, tiling=args.tiling)
    write_image(args.output, image)
    print(f"wrote {os.path.abspath(args.output)} ({args.size} x {args.size})")


if __name__ == "__main__":
    main()
