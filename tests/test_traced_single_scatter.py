"""`single_scatter_samples N`: single scattering traced inside the object's own shape
(RandomWalk::single_scatter through the renderer's intersections and lights), checked on the
rendered pixel (+FE32):

* a sphere of Jensen's Skin1 (eta 1, g 0) one diffusion length in radius, light from
  normalize(1, 0.5, 1), orthographic view from +z: the single-scattering flux of the image (the
  render with it minus the render with ``single_scatter off``) against the sphere's exact single
  scattering integrated here in numpy (ray-sphere distances along every view ray, nothing of the
  library). The half-space formula, the default, is the control: it misses 14 % of it;
* a large flat block under slanted light and view: on a flat face the traced sum is the
  half-space formula itself, pixel by pixel;
* a thin Ketchup sheet lit from above, seen from either side, against the harness's volumetric
  reference (exact transport, numpy): single scattering counted once on both faces (the slab's
  transmitted face then holds multiple scattering only); the default, the control, is far off.

Tolerances, stated before measuring: the sphere's single-scattering flux within 1 % at 32 depths
per channel (the sum's own error on a curved face, measured on the library's slab closed forms at
0.2 %, plus the image's pixel sampling); the control at least 5 % off; the flat block within
1e-6 of the default render per pixel (only rounding separates them); the sheet within 3 % (issue
31's bound) beyond 4 of the reference's standard errors, its default at least 50 % off.
"""

from __future__ import annotations

import numpy as np

from harness.core import runner
from harness.reference import volume_ref
from harness.reports import walk_bench as wb

#: the traced single scattering of the sphere against the numpy integral (relative, per channel)
SPHERE_SINGLE_TOL = 0.01
#: the half-space formula (the default) on the same sphere: at least this far off (the control)
SPHERE_HALFSPACE_OFF = 0.05
#: a flat face: traced and formula renders per pixel (relative to the brightest)
FLAT_TRACED_TOL = 1e-6

LIGHT = np.array([1.0, 0.5, 1.0]) / 1.5
VIEW = np.array([0.0, 0.0, 1.0])


def sphere_single_flux(sigma_s: float, sigma_a: float, radius: float, npx: int = 256, nt: int = 400) -> float:
    """Single-scattering flux (pi L / E integrated over the image plane) of an index-matched,
    isotropically scattering sphere at the origin seen from +z and lit along LIGHT: along every
    view ray, depths uniform in 1 - exp(-sigma_t t) over the chord, the light's path back to the
    surface by the ray-sphere distance, phase 1 / (4 pi)."""
    st = sigma_s + sigma_a
    span = 2.2 * radius
    pix = span / npx
    c = (np.arange(npx) + 0.5) * pix - span / 2
    x, y = np.meshgrid(c, c)
    inside = x ** 2 + y ** 2 < radius ** 2
    x, y = x[inside], y[inside]
    z0 = np.sqrt(radius ** 2 - x ** 2 - y ** 2)
    umax = 1.0 - np.exp(-st * 2.0 * z0)
    u = (np.arange(nt) + 0.5)[None, :] / nt * umax[:, None]
    t = -np.log1p(-u) / st
    p = np.stack([np.broadcast_to(x[:, None], t.shape), np.broadcast_to(y[:, None], t.shape), z0[:, None] - t], -1)
    b = p @ LIGHT
    s = -b + np.sqrt(np.maximum(b * b - ((p ** 2).sum(-1) - radius ** 2), 0.0))
    radiance = sigma_s / (4 * np.pi) * (umax / st) * np.exp(-st * s).mean(axis=1)
    return float((np.pi * radiance).sum() * pix * pix)


def sphere_flux(fork, radius: float, extra: str, size: int = 64) -> np.ndarray:
    right, up = volume_ref.image_axes(VIEW)
    span = 2.2 * radius
    text = wb.SPHERE.format(far=10 * radius, right=wb.vec(span * right), up=wb.vec(span * up), light=wb.vec(LIGHT),
                            r=radius, dipole=wb.medium_text("Skin1", 0.0, 1.0) + " " + extra)
    img = runner.render(text, fork, width=size, height=size, float_exr=True, threads=2).image[..., :3]
    return img.astype(np.float64).sum(axis=(0, 1)) * (span / size) ** 2


def test_a_small_sphere_gets_its_exact_single_scattering(fork):
    radius = wb.diffusion_length("Skin1")
    ss, sa = wb.coefficients("Skin1", 0.0)
    exact = np.array([sphere_single_flux(s, a, radius) for s, a in zip(ss, sa)])
    none = sphere_flux(fork, radius, "single_scatter off")
    traced = sphere_flux(fork, radius, "single_scatter_samples 32") - none
    formula = sphere_flux(fork, radius, "") - none
    err, control = traced / exact - 1, formula / exact - 1
    print("traced", np.round(100 * err, 2), "% ; half-space formula", np.round(100 * control, 2), "%")
    assert np.all(np.abs(err) < SPHERE_SINGLE_TOL)
    assert np.all(np.abs(control) > SPHERE_HALFSPACE_OFF)


FLAT = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ orthographic location <0.8, 0.3, 10> direction <-0.08, -0.03, -1> right x*4 up y*4 }}
light_source {{ <-1, 0.4, 0.9> * 1000 rgb <1, 0.9, 0.8> parallel point_at <0, 0, 0> }}
box {{ <-200, -200, -100>, <200, 200, 0>
  texture {{ pigment {{ rgb 1 }} finish {{ ambient 0 dipole {{ "Skin1" ior 1.3 mm_per_unit 1 {extra} }} }} }} }}
"""


def test_on_a_flat_face_the_traced_sum_is_the_formula(fork):
    ra = runner.render(FLAT.format(extra=""), fork, width=24, height=24, float_exr=True)
    rb = runner.render(FLAT.format(extra="single_scatter_samples 4"), fork, width=24, height=24, float_exr=True)
    a, b = ra.image[..., :3], rb.image[..., :3]
    # the statistics say which points had it traced (every pixel here), and only when asked for
    assert "Dipole traced single scattering:" in rb.stderr
    assert "Dipole traced single scattering:" not in ra.stderr
    worst = float(np.abs(b.astype(np.float64) - a).max() / a.max())
    print(f"flat face: traced vs formula, worst pixel {worst:.2e} of the brightest")
    assert a.max() > 0
    assert worst < FLAT_TRACED_TOL


#: a thin sheet with single scattering traced, against exact transport (issue 31's 3 %), beyond
#: 4 of the reference's standard errors
SHEET_TOL = 0.03
#: (the default, the flat slab's own single scattering at each lookup since 2026-12-06, is held
#: to the same SHEET_TOL: before, the half-space formula on the lit side and the slab's
#: transmitted face holding single scattering, it was 1.16 off lit, 0.48 behind)


def test_a_back_lit_sheet_counts_single_scattering_once(fork):
    """A Ketchup sheet (eta 1, g 0) 0.25 transport mean free paths thick, lit straight from above,
    seen straight from above and from below: the centre pixels against volume_ref.sheet (a numpy
    photon tracer sharing no code with the library), every channel. Measured (walk_bench):
    traced 0.50 % (lit side) and 0.56 % (behind); the default the same since it adds the flat
    slab's own single scattering (2026-12-06; before: +119 % and +49 %, +348 % behind before
    the tables were continued below their first albedo node); ``directional on`` the same since
    its single scattering from upstream gets the slab's correction too (2026-12-06, second
    session; before: the half-space's, +109 / +71 / +44 % on the lit side of a Skin1 sheet)."""
    ss, sa = wb.coefficients("Ketchup", 0.0)
    d = 0.25 * wb.longest_mfp("Ketchup")
    views = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    ref = volume_ref.sheet(ss, sa, 0.0, 1.0, d, [0, 0, 1], views, n_paths=100_000, seed=13)
    worst = {}
    for extra in ("single_scatter_samples 16", "", "directional on"):
        for k, view in enumerate(views):
            right = np.array([1.0, 0.0, 0.0])
            up = np.cross(view, right)
            cam = dict(loc=wb.vec(60 * view + np.array([0, 0, -d if view[2] < 0 else 0])), dir=wb.vec(-view),
                       right=wb.vec(2 * right), up=wb.vec(2 * up))
            text = wb.SHEET.format(bottom=-d, dipole=wb.medium_text("Ketchup", 0.0, 1.0) + " " + extra, **cam)
            got = runner.render(text, fork, width=8, height=8, float_exr=True).image[..., :3].reshape(-1, 3).mean(0)
            want, err = ref.radiance[:, k], ref.radiance_err[:, k]
            rel = np.abs(got / want - 1) - 4 * err / want
            worst[(extra, k)] = float(rel.max())
            print(f"{extra or 'default':28s} {'lit side' if k == 0 else 'behind  '}: {np.round(100 * (got / want - 1), 2)} % "
                  f"(reference +- {np.round(100 * err / want, 2)} %)")
    print("worst beyond 4 standard errors:", worst)
    for key, value in worst.items():
        assert value < SHEET_TOL, key


#: a forward-scattering sheet seen along the light: the traced single scattering against the sum
#: over depth below (relative, per channel), 16 depths per channel
MIRRORED_VIEW_TOL = 0.01


def slab_single_straight_on(sigma_s: float, sigma_a: float, g: float, eta: float, d: float,
                            mirror_view: bool = True) -> float:
    """pi L / E of single scattering leaving the lit face of a slab lit and seen straight on,
    summed over depth here in numpy: the beam mirrored by either face any number of times, the
    scattered light mirrored by either face any number of times on its way to the eye (or, with
    ``mirror_view`` False, leaving straight up from where it scattered), Henyey-Greenstein phase at
    0 and 180 degrees, Fresnel at normal incidence."""
    st = sigma_s + sigma_a
    r = ((eta - 1) / (eta + 1)) ** 2
    p_fwd = (1 - g * g) / (4 * np.pi * (1 - g) ** 3)
    p_back = (1 - g * g) / (4 * np.pi * (1 + g) ** 3)
    z = np.linspace(0.0, d, 20001)
    m = np.arange(12)[:, None]
    down = (r ** (2 * m) * np.exp(-st * (2 * m * d + z))).sum(0)  # the beam going down at depth z
    up = (r ** (2 * m + 1) * np.exp(-st * ((2 * m + 2) * d - z))).sum(0)  # and going up
    to_eye_up = np.trapezoid(sigma_s * (p_back * down + p_fwd * up) * np.exp(-st * z), z)
    total = to_eye_up
    if mirror_view:
        # scattered down, mirrored by the far face, then up to the eye; any number of round trips
        to_eye_down = np.trapezoid(sigma_s * (p_fwd * down + p_back * up) * np.exp(-st * (d - z)), z) * r * np.exp(-st * d)
        total = (to_eye_up + to_eye_down) / (1 - r * r * np.exp(-2 * st * d))
    return float(np.pi * (1 - r) ** 2 / eta ** 2 * total)


def test_a_forward_scattering_sheet_seen_along_the_light_keeps_its_mirrored_view(fork):
    """Skin1 at g 0.9 (eta 1.3), a sheet 0.25 transport mean free paths thick, lit and seen
    straight on from above: most of its single scattering is the forward peak, light scattered
    toward the far face and mirrored there to the eye, or the beam mirrored there and scattered
    on toward the eye. The traced sum (the render with it minus ``single_scatter off``) against
    slab_single_straight_on; the view path left straight is the control (45 % short). Measured:
    -0.08 / -0.06 / +0.02 % (16 depths); before the view path was mirrored, -51 / -49 / -42 %."""
    ss, sa = wb.coefficients("Skin1", 0.9)
    d = 0.25 * wb.longest_mfp("Skin1")
    cam = wb.sheet_camera(np.array([0.0, 0.0, 1.0]), d)
    got = {}
    for extra in ("single_scatter_samples 16", "single_scatter off"):
        text = wb.SHEET.format(bottom=-d, dipole=wb.medium_text("Skin1", 0.9, 1.3) + " " + extra, **cam)
        got[extra] = runner.render(text, fork, width=8, height=8, float_exr=True).image[..., :3].reshape(-1, 3).mean(0)
    traced = got["single_scatter_samples 16"] - got["single_scatter off"]
    for c in range(3):
        want = slab_single_straight_on(ss[c], sa[c], 0.9, 1.3, d)
        straight = slab_single_straight_on(ss[c], sa[c], 0.9, 1.3, d, mirror_view=False)
        print(f"channel {c}: traced {traced[c]:.6f}, summed {want:.6f} ({100 * (traced[c] / want - 1):+.2f} %), "
              f"the view path straight {straight:.6f}")
        assert straight < 0.7 * want  # the mirrored view is what this checks
        assert abs(traced[c] / want - 1) < MIRRORED_VIEW_TOL


def test_asking_for_it_with_single_scattering_off_says_so(fork):
    """`profile dipole` leaves single scattering off (its Rd stands for it): single_scatter_samples
    then does nothing, and the user is told so at the block, not left guessing."""
    text = FLAT.format(extra="profile dipole single_scatter_samples 8")
    r = runner.render(text, fork, width=8, height=8)
    notes = [w for w in r.warnings if "single_scatter_samples has no effect" in w]
    assert len(notes) == 1 and "single_scatter on" in notes[0]
    on = runner.render(FLAT.format(extra="profile dipole single_scatter on single_scatter_samples 8"), fork, width=8,
                       height=8)
    assert not any("single_scatter_samples has no effect" in w for w in on.warnings)
