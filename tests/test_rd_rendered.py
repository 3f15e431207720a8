"""The radial profile as rendered (issue 31's "Rd(r) as rendered"): a half-space of Jensen's Skin1
red channel (sigma_s' 0.74, sigma_a 0.032 /mm, ior 1.3) lit straight down through a round hole of
radius 0.5 mfp', seen straight down, the means of the rendered pi L over annuli from 1 to 10
mfp' against `volume_ref.spot` (harness.reference, a numpy photon tracer sharing no code with
the library), in the annuli where the reference's own error is below 2.5 %.

Tolerances fixed before measuring. EXACT_RD_TO_10 is the issue's goal (5 %): the exit
distribution changes with the distance from the entry point, and the tables carry it per band
of distance (shading/DIPOLE.md 10.3, 10.7); with uniform light's at every distance the render
was too bright near the hole at normal view (8.0 % here at sample spacing 0.25, 6.8 % at 0.1).
The scene and reference are seeded: the measured value is the same every run. The control: the
classical dipole's profile is far off in the same annuli. Two more channels where the profile
used to fail: Ketchup's blue at ior 1.3 (alpha' 0.02, below the tables' first albedo node) and
its green at ior 1 (the distance bands' curve keeping each band's mean), both ss_profile.cpp.
"""

from __future__ import annotations

import numpy as np

from harness.core import runner
from harness.reference import volume_ref
from harness.reports import walk_bench as wb

#: Worst |render / reference - 1| over the judged annuli to 10 mfp' (measured 0.023; 0.041 before
#: the hole's rim samples took their cells' mean light, DIPOLE.md 6, 2a).
EXACT_RD_TO_10 = 0.05
#: The same with `profile dipole`: at least this far off (measured 0.52).
DIPOLE_RD_TO_10 = 0.3


def _worst_to_10(extra: str, medium: str = "Skin1", channel: int = 0, least_judged: int = 6, eta: float = 1.3,
                 paths: int = 40_000) -> float:
    ss, sa = wb.coefficients(medium, 0.0)
    sp = np.array(wb.MEDIA[medium][0])
    mfp = float(1.0 / (sp[channel] + sa[channel]))
    size = float(wb.RD_MFP[-1])
    text = wb.spot_scene(ss[channel], sa[channel], 0.0, eta, mfp, extra)
    r = runner.render(text, "fork", width=512, height=512, float_exr=True, threads=2)
    img = r.image[..., :3].astype(np.float64)
    assert np.isfinite(img).all()
    edges = wb.RD_MFP[wb.RD_MFP <= 10.0]  # the annuli from 1 to 9.65 mfp'
    got = wb.annulus_means(img[..., :1], size, edges)[0]
    ref = volume_ref.spot([ss[channel]], [sa[channel]], 0.0, eta, wb.RD_HOLE * mfp, edges * mfp, n_paths=paths,
                          seed=23 + channel)
    want, err = ref.radiance[0], ref.radiance_err[0]
    judged = err < wb.RD_REF_NOISE * want
    assert judged.sum() >= least_judged, (want, err)
    rel = got[judged] / want[judged] - 1
    print(f"{medium} {'RGB'[channel]} ior {eta} {extra or 'default'}: " + " ".join(f"{v:+.3f}" for v in rel))
    return float(np.abs(rel).max())


def test_exact_profile_as_rendered_follows_exact_transport():
    assert _worst_to_10("") <= EXACT_RD_TO_10


def test_a_low_albedo_channel_as_rendered_follows_exact_transport():
    # Ketchup's blue (alpha' 0.02, below the tables' first albedo node): the reference resolves
    # it to 2.7 mfp' (4 annuli). Same goal as above.
    assert _worst_to_10("", "Ketchup", 2, least_judged=3) <= EXACT_RD_TO_10


def test_near_the_entry_point_at_ior_1():
    # Ketchup's green (alpha' 0.067) at ior 1: its exit distribution toward the normal changes
    # fastest with distance, so the distance bands' curve must keep each band's own mean
    # (ss_profile.cpp). Same goal as above; 160 000 reference paths (noise 0.6-1.5 %, at low
    # albedo they are short).
    assert _worst_to_10("", "Ketchup", 1, least_judged=3, eta=1.0, paths=160_000) <= EXACT_RD_TO_10


def test_control_the_dipole_profile_does_not():
    assert _worst_to_10("profile dipole") >= DIPOLE_RD_TO_10
