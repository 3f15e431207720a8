"""Directional albedo of a tabulated BRDF, integrated in numpy from the table's own nodes.

The independent check of a table finish's glossy reflection (``samples N``): in a white
furnace a pixel's expected value is the directional albedo ``a(theta_o) = integral of
f(theta_i, theta_o, phi) cos(theta_i) dw_i`` of the *interpolated* table. This module
interpolates the nodes trilinearly (the table format's documented lookup,
``brdf_data/README.md``) at the midpoints of a sub-grid (``sub`` points per table cell and
axis) and sums with ``cos(theta_i) sin(theta_i)`` weights; it shares no code with the C++
table, its albedo nodes or its sampler. With ``sub = 2`` on a 1 deg table the midpoint rule's
own error is far below 1e-4 (the integrand is bilinear in phi and smooth in theta).
"""

from __future__ import annotations

import numpy as np

__all__ = ["table_albedo", "halfdiff_albedo"]


def _weights(x: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lower node, upper node and weight of the upper node for positions x in node units."""
    x = np.clip(x, 0.0, n - 1)
    i0 = np.minimum(x.astype(np.int64), n - 2)
    return i0, i0 + 1, x - i0


def table_albedo(f: np.ndarray, theta_o_deg: np.ndarray, sub: int = 2) -> np.ndarray:
    """Albedo per channel, shape (len(theta_o_deg), C), of an isotropic table ``f``.

    ``f`` has shape (n_theta_i, n_theta_r, n_phi, C) with theta on [0, 90] deg and phi on
    [0, 180] deg at equal steps (as :func:`harness.core.brdf_io.read_brdf` returns it, folded
    tables unfolded). The viewer is on the theta_r axis, the light on theta_i.
    """
    f = np.array(f, dtype=np.float64)
    n_i, n_r, n_p, channels = f.shape
    # The format's pole rule: at theta = 0 the azimuth is undefined, so a lookup reads the
    # mean over phi of each theta_i = 0 and theta_r = 0 row.
    f[0] = f[0].mean(axis=1, keepdims=True)
    f[:, 0] = f[:, 0].mean(axis=1, keepdims=True)
    step_i, step_p = 90.0 / (n_i - 1), 180.0 / (n_p - 1)
    # Midpoints of `sub` x `sub` sub-cells of every (theta_i, phi) cell.
    ti_edges = np.linspace(0.0, 90.0, (n_i - 1) * sub + 1)
    ti = 0.5 * (ti_edges[1:] + ti_edges[:-1])
    # Exact integral of cos sin over each theta band, times the phi width (both signs of phi).
    band = 0.5 * (np.sin(np.radians(ti_edges[1:])) ** 2 - np.sin(np.radians(ti_edges[:-1])) ** 2)
    n_sub_p = (n_p - 1) * sub
    phi = (np.arange(n_sub_p) + 0.5) * (180.0 / n_sub_p)
    dphi = 2.0 * np.radians(180.0 / n_sub_p)
    i0, i1, wi = _weights(ti / step_i, n_i)
    p0, p1, wp = _weights(phi / step_p, n_p)
    out = np.zeros((len(np.atleast_1d(theta_o_deg)), channels))
    for k, to in enumerate(np.atleast_1d(theta_o_deg)):
        r0, r1, wr = _weights(np.array([to / (90.0 / (n_r - 1))]), n_r)
        r0, r1, wr = int(r0[0]), int(r1[0]), float(wr[0])
        # f at theta_o: linear between the two theta_r planes.
        plane = (1 - wr) * f[:, r0] + wr * f[:, r1]  # (n_i, n_p, C)
        # Bilinear in (theta_i, phi) at every sub-cell midpoint.
        a = plane[i0][:, p0] * ((1 - wi)[:, None, None] * (1 - wp)[None, :, None])
        a += plane[i1][:, p0] * (wi[:, None, None] * (1 - wp)[None, :, None])
        a += plane[i0][:, p1] * ((1 - wi)[:, None, None] * wp[None, :, None])
        a += plane[i1][:, p1] * (wi[:, None, None] * wp[None, :, None])
        out[k] = np.einsum("ipc,i->c", a, band) * dphi
    return out


def halfdiff_albedo(f: np.ndarray, theta_o_deg: np.ndarray, rows: int = 360, cols: int = 180) -> np.ndarray:
    """Albedo per channel, shape (len(theta_o_deg), C), of a half/difference table ``f``
    (theta_h, theta_d, phi_d, C), read by :func:`harness.core.brdf_io.halfdiff_lookup`.

    The integral runs over the half vector h, where a narrow lobe is compact:
    ``a(theta_o) = integral of f(wo, wi) cos(theta_i) 4 (wo . h) dw_h`` with wi the reflection
    of wo about h (dw_i = 4 (wo . h) dw_h), on a midpoint grid uniform in sqrt(theta_h) (``rows``
    bands with exact solid angles, so the finest bands sit at the normal where a narrow lobe is)
    and in the azimuth of h from the viewer's plane over [0, pi] (``cols``, doubled: the table is
    even in it). Shares no code with the C++ table or its sampler.
    """
    from harness.core.brdf_io import halfdiff_lookup

    u = np.linspace(0.0, 1.0, rows + 1)
    th_edges = (np.pi / 2) * u ** 2
    th = (np.pi / 2) * (0.5 * (u[1:] + u[:-1])) ** 2
    band = np.cos(th_edges[:-1]) - np.cos(th_edges[1:])      # solid angle per unit azimuth
    ph = (np.arange(cols) + 0.5) * (np.pi / cols)
    dph = 2.0 * np.pi / cols                                   # both sides of the plane
    T, P = np.meshgrid(th, ph, indexing="ij")
    h = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1).reshape(-1, 3)
    weight = np.repeat(band, cols) * dph
    out = []
    for to in np.atleast_1d(theta_o_deg):
        t = np.radians(min(float(to), 89.999))
        wo = np.array([np.sin(t), 0.0, np.cos(t)])
        d = h @ wo
        wi = 2.0 * d[:, None] * h - wo
        ok = (d > 0) & (wi[:, 2] > 0)
        wi_ok = wi[ok] / np.linalg.norm(wi[ok], axis=1, keepdims=True)
        val = halfdiff_lookup(f, wi_ok, np.broadcast_to(wo, wi_ok.shape))
        g = val * (wi_ok[:, 2] * 4.0 * d[ok] * weight[ok])[:, None]
        out.append(g.sum(axis=0))
    return np.array(out)
