"""Turn the rendered frames of ball.pov into "photographs" (docs/fitting.md): multiplicative
noise on every pixel, and a description, photos.toml, whose light directions are off by a
small calibration error (every light turned by ERROR_DEG about the image's x axis).

    python3 photos.py [--noise 0.02] [--error-deg 1.5] [--frames 35]     (in the render folder)
"""

import argparse
import math

import numpy as np

from harness.core import exr

ap = argparse.ArgumentParser()
ap.add_argument("--noise", type=float, default=0.02, help="relative noise per pixel and channel (default 0.02)")
ap.add_argument("--error-deg", type=float, default=1.5, help="light direction error, degrees (default 1.5)")
ap.add_argument("--frames", type=int, default=35)
ap.add_argument("--seed", type=int, default=1)
a = ap.parse_args()
rng = np.random.default_rng(a.seed)
digits = len(str(a.frames - 1))
e = math.radians(a.error_deg)
lines = ['# How the photographs were taken (ball.pov; light directions off by %g deg)' % a.error_deg,
         '[image]', 'values = "pov"          # POV-Ray render: pixel = pi x radiance', 'width = 200', 'height = 200',
         '[camera]', 'type = "orthographic"', 'position = [0, 0, -10]', 'look = [0, 0, 1]', 'up = [0, 1, 0]',
         'width = 2.2', '[sphere]', 'centre = [0, 0, 0]', 'radius = 1']
for k in range(a.frames):
    name = f"ball{k:0{digits}d}.exr"
    img = exr.read_exr(name)
    exr.write_exr(f"photo{k:0{digits}d}.exr", img * (1 + a.noise * rng.standard_normal(img.shape)))
    g, t = math.radians(5 * k), math.radians(20 + 37 * k)
    x, y, z = math.sin(g) * math.cos(t), math.sin(g) * math.sin(t), -math.cos(g)
    y, z = y * math.cos(e) - z * math.sin(e), y * math.sin(e) + z * math.cos(e)  # the calibration error
    lines += ["[[photo]]", f'file = "photo{k:0{digits}d}.exr"',
              f"light = {{ direction = [{x:.6f}, {y:.6f}, {z:.6f}], irradiance = 1.0 }}"]
open("photos.toml", "w").write("\n".join(lines) + "\n")
print(f"photos.toml: {a.frames} photographs, noise {a.noise:g}, light directions off by {a.error_deg:g} deg")
