"""The named-material include files scenes/include/brdf_metals.inc and brdf_fits.inc.

(a) Every ``#declare F_...`` finish of each file parses and renders with the fork (one small
    render per file, one sphere per finish, the file included twice through its guard), and
    the image is finite and non-negative, with every sphere lit.
(b) The metals' declared optical constants: they are the cited tables interpolated as the file
    says, and the normal-incidence reflectance R0 = ((n-1)^2 + k^2) / ((n+1)^2 + k^2) they give
    agrees with independently *measured* reflectances (Spisz et al. 1969) within the limits
    argued at each check.
Closed-form checks of the rendered models themselves live with the model tests.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from harness.core import runner
from harness.core.paths import repo_root

INCLUDE_DIR = repo_root() / "scenes" / "include"
FILES = ("brdf_metals.inc", "brdf_fits.inc")
#: Finishes each file must declare at least (catches a broken name pattern, not a cap).
MIN_FINISHES = {"brdf_metals.inc": 24, "brdf_fits.inc": 11}
CELL = 24  # pixels per sphere

WAVELENGTHS_NM = (650.0, 550.0, 450.0)  # R, G, B channels of brdf_metals.inc


def include_text(name: str) -> str:
    return (INCLUDE_DIR / name).read_text()


def finish_names(name: str) -> list[str]:
    return re.findall(r"^\s*#declare\s+(F_\w+)\s*=", include_text(name), re.MULTILINE)


def declared_vectors(text: str) -> dict[str, tuple[float, float, float]]:
    out = {}
    for m in re.finditer(r"#declare\s+(\w+)\s*=\s*<([^>]*)>\s*;", text):
        out[m.group(1)] = tuple(float(x) for x in m.group(2).split(","))
    return out


def grid_scene(include: str, names: list[str]) -> tuple[str, int, int]:
    """One unit sphere per finish on a grid, orthographic camera, one cell of CELL px each."""
    cols = math.ceil(math.sqrt(len(names)))
    rows = math.ceil(len(names) / cols)
    lines = [
        "#version 3.7;",
        f'#include "{include}"',
        f'#include "{include}"',  # twice: the POV-style include guard must make this a no-op
        "global_settings { assumed_gamma 1.0 }",
        f"camera {{ orthographic location <{cols}, {-rows}, -10> direction z "
        f"right x*{2 * cols} up y*{2 * rows} }}",
        # parallel light near the view direction: every sphere shows its highlight and body
        "light_source { <-3, 4, -10> * 1000 rgb 1 parallel point_at 0 }",
    ]
    for i, n in enumerate(names):
        r, c = divmod(i, cols)
        lines.append(f"sphere {{ <{2 * c + 1}, {-(2 * r + 1)}, 0>, 0.95 finish {{ {n} }} }}")
    return "\n".join(lines) + "\n", cols * CELL, rows * CELL


@pytest.mark.parametrize("include", FILES)
def test_every_named_finish_renders(fork, include):
    names = finish_names(include)
    assert len(names) >= MIN_FINISHES[include], names
    assert len(set(names)) == len(names), "duplicate finish names"
    assert all(n.startswith("F_BRDF_") for n in names), names
    text, w, h = grid_scene(include, names)
    res = runner.render(text, fork, width=w, height=h, float_exr=True, threads=2)
    img = res.image
    assert np.isfinite(img).all()
    assert (img >= 0).all()
    assert not res.warnings, res.warnings
    cols = w // CELL
    for i, n in enumerate(names):
        r, c = divmod(i, cols)
        cell = img[r * CELL:(r + 1) * CELL, c * CELL:(c + 1) * CELL]
        assert cell.max() > 0.0, f"{n}: sphere renders black"


# ---------------------------------------------------------------- (b) optical constants

#: The rows of the cited tables that bracket 650, 550 and 450 nm: (um, n, k), (um, n, k).
#: Au, Ag, Cu: Johnson & Christy 1972, Phys. Rev. B 6, 4370, Table I. Cr, Fe, Ni, Ti: Johnson &
#: Christy 1974, Phys. Rev. B 9, 5056. Al: Rakic 1995, Appl. Opt. 34, 4755. (Read from the
#: refractiveindex.info database transcriptions, database/data-nk/main/<metal>/.)
SOURCE_ROWS = {
    "Gold": [((0.6168, 0.21, 3.272), (0.6595, 0.14, 3.697)),
             ((0.5486, 0.43, 2.455), (0.5821, 0.29, 2.863)),
             ((0.4305, 1.45, 1.948), (0.4509, 1.38, 1.914))],
    "Silver": [((0.6168, 0.06, 4.152), (0.6595, 0.05, 4.483)),
               ((0.5486, 0.06, 3.586), (0.5821, 0.05, 3.858)),
               ((0.4305, 0.04, 2.462), (0.4509, 0.04, 2.657))],
    "Copper": [((0.6168, 0.30, 3.205), (0.6595, 0.22, 3.747)),
               ((0.5486, 1.02, 2.577), (0.5821, 0.70, 2.704)),
               ((0.4305, 1.25, 2.305), (0.4509, 1.24, 2.397))],
    "Aluminium": [((0.61993, 1.3660, 7.4052), (0.65225, 1.5724, 7.7354)),
                  ((0.51660, 0.8734, 6.2418), (0.56357, 1.0728, 6.7839)),
                  ((0.44280, 0.6079, 5.3676), (0.47687, 0.7278, 5.7781))],
    "Chromium": [((0.617, 3.17, 3.30), (0.659, 3.09, 3.34)),
                 ((0.549, 3.18, 3.33), (0.582, 3.22, 3.30)),
                 ((0.431, 2.19, 3.04), (0.451, 2.33, 3.14))],
    "Iron": [((0.617, 2.88, 3.05), (0.659, 2.92, 3.10)),
             ((0.549, 2.95, 2.93), (0.582, 2.94, 2.99)),
             ((0.431, 2.48, 2.71), (0.451, 2.59, 2.77))],
    "Nickel": [((0.617, 1.99, 4.02), (0.659, 1.99, 4.26)),
               ((0.549, 1.92, 3.61), (0.582, 1.96, 3.80)),
               ((0.431, 1.71, 2.82), (0.451, 1.73, 2.95))],
    "Titanium": [((0.617, 2.67, 3.72), (0.659, 2.76, 3.84)),
                 ((0.549, 2.54, 3.43), (0.582, 2.60, 3.58)),
                 ((0.431, 2.21, 3.01), (0.451, 2.27, 3.04))],
}

#: Measured total (integrating-sphere) reflectance of polished bulk samples at 294 K:
#: E. W. Spisz, A. J. Weigand, R. L. Bowman, J. R. Jack (1969), "Solar absorptances and spectral
#: reflectances of 12 metals for temperatures ranging from 300 to 500 K", NASA TN D-5353,
#: Table II(a) (read from the photobiologyFilters R package, data-raw/metals/Spisz.metals.data).
#: Rows bracketing 450, 550 and 650 nm: wavelength (um) -> reflectance.
SPISZ_WL = (0.444, 0.457, 0.540, 0.554, 0.647, 0.665)
SPISZ = {
    "Aluminium": (0.855, 0.864, 0.863, 0.870, 0.872, 0.876),
    "Copper": (0.334, 0.348, 0.463, 0.494, 0.832, 0.840),
    "Gold": (0.340, 0.338, 0.749, 0.794, 0.922, 0.929),
    "Nickel": (0.498, 0.508, 0.566, 0.571, 0.626, 0.626),
    "Silver": (0.835, 0.831, 0.888, 0.913, 0.958, 0.957),
    "Titanium": (0.186, 0.192, 0.213, 0.236, 0.274, 0.275),
}


def metal_constants() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    vecs = declared_vectors(include_text("brdf_metals.inc"))
    out = {}
    for metal in SOURCE_ROWS:
        out[metal] = (np.array(vecs[f"BRDF_{metal}_N"]), np.array(vecs[f"BRDF_{metal}_K"]))
    return out


def r0(n: np.ndarray, k: np.ndarray) -> np.ndarray:
    return ((n - 1) ** 2 + k ** 2) / ((n + 1) ** 2 + k ** 2)


def spisz_at(metal: str) -> np.ndarray:
    """Spisz reflectance linearly interpolated to 650, 550, 450 nm (R, G, B)."""
    return np.array([np.interp(w / 1000.0, SPISZ_WL, SPISZ[metal]) for w in WAVELENGTHS_NM])


def test_wavelengths_declared():
    vecs = declared_vectors(include_text("brdf_metals.inc"))
    assert vecs["BRDF_Metals_Wavelengths"] == WAVELENGTHS_NM


@pytest.mark.parametrize("metal", sorted(SOURCE_ROWS))
def test_constants_are_the_cited_rows_interpolated(metal):
    # Linear in wavelength between the bracketing rows, rounded to 3 decimals: the declared
    # value may differ from the exact interpolation by half a unit of the 3rd decimal.
    n, k = metal_constants()[metal]
    for c, (wl, (lo, hi)) in enumerate(zip(WAVELENGTHS_NM, SOURCE_ROWS[metal])):
        w = wl / 1000.0
        assert lo[0] <= w <= hi[0]
        f = (w - lo[0]) / (hi[0] - lo[0])
        assert abs(n[c] - (lo[1] + f * (hi[1] - lo[1]))) <= 5e-4 + 1e-12, (metal, wl, "n")
        assert abs(k[c] - (lo[2] + f * (hi[2] - lo[2]))) <= 5e-4 + 1e-12, (metal, wl, "k")
    # ... and the file quotes these rows in the comment above the values
    text = include_text("brdf_metals.inc")
    before = text[:text.index(f"#declare BRDF_{metal}_N")]
    quoted = QUOTED_ROW.findall(before)[-3:]
    assert [int(q[0]) for q in quoted] == [650, 550, 450]
    for q, (lo, hi) in zip(quoted, SOURCE_ROWS[metal]):
        assert tuple(float(x) for x in q[1:]) == lo + hi, (metal, q)


#: "//   650 nm: 0.6168 0.21 3.272 | 0.6595 0.14 3.697" in brdf_metals.inc
QUOTED_ROW = re.compile(r"//\s+(\d+) nm:\s+([\d.]+) ([\d.]+) ([\d.]+) \| ([\d.]+) ([\d.]+) ([\d.]+)")


@pytest.mark.parametrize("metal", sorted(SPISZ))
def test_r0_not_below_measured_reflectance(metal):
    # R0 from optical constants of clean films is the reflectance of an ideal smooth, clean
    # surface. Spisz measured polished bulk samples in air: roughness, oxide and contamination
    # can only lower a real surface's reflectance. So R0 must not fall below the measurement,
    # except by the measurement's own noise: the largest point-to-point scatter of their
    # table on the smooth spectra (Al, Ni, Ag, Ti; |R_i - (R_i-1 + R_i+1)/2|, 415-700 nm) is
    # 0.020, which is the tolerance.
    n, k = metal_constants()[metal]
    got, meas = r0(n, k), spisz_at(metal)
    assert (got >= meas - 0.020).all(), (metal, got, meas)


@pytest.mark.parametrize("metal", sorted(SPISZ))
def test_r0_has_the_measured_colour(metal):
    # Where the measured spectrum rises from blue to red by more than the scatter above
    # (0.02) plus the 0.03 margin of "clearly coloured", R0 must rise too; where it is flat
    # (aluminium, 0.859 -> 0.873), R0 must be neutral within the same 0.05.
    n, k = metal_constants()[metal]
    got, meas = r0(n, k), spisz_at(metal)
    if meas[0] - meas[2] > 0.05:
        assert got[0] > got[2], (metal, got, meas)
    else:
        assert abs(got[0] - got[2]) < 0.05, (metal, got, meas)


def test_gold_r0_within_polished_gold_spread():
    # Pure gold: "a range of up to 15 percent in reflectivity" was measured on different,
    # apparently flawless polished surfaces (Economic Geology 62(3), 412 (1967), "Reflectivity
    # of gold and gold-silver alloys", abstract). So the clean-film R0 may exceed Spisz's
    # polished sample by at most 0.15 in each channel. And it is yellow: red above 0.9 and blue
    # below 0.5, as measured (Spisz: 0.923 at 650 nm, 0.339 at 450 nm; 0.02 scatter).
    n, k = metal_constants()["Gold"]
    got, meas = r0(n, k), spisz_at("Gold")
    assert (got - meas <= 0.15).all(), (got, meas)
    assert got[0] > 0.9 and got[2] < 0.5, got


def test_every_metal_has_its_finishes():
    names = set(finish_names("brdf_metals.inc"))
    for metal in SOURCE_ROWS:
        for grade in ("Polished", "Satin", "Rough"):
            assert f"F_BRDF_{metal}_{grade}" in names
