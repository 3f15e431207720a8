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

__all__ = ["table_albedo", "halfdiff_albedo", "channel_floor", "shared_floor"]


def _weights(x: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lower node, upper node and weight of the upper node for positions x in node units."""
    x = np.clip(x, 0.0, n - 1)
    i0 = np.minimum(x.astype(np.int64), n - 2)
    return i0, i0 + 1, x - i0


def _table_cells(f: np.ndarray, theta_o_deg: np.ndarray, sub: int = 2):
    """Per viewing angle, f cos(theta_i) dw_i of every sub-cell midpoint of an isotropic table,
    shape (cells, C): their sum is the albedo (see :func:`table_albedo`)."""
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
    for to in np.atleast_1d(theta_o_deg):
        r0, r1, wr = _weights(np.array([to / (90.0 / (n_r - 1))]), n_r)
        r0, r1, wr = int(r0[0]), int(r1[0]), float(wr[0])
        # f at theta_o: linear between the two theta_r planes.
        plane = (1 - wr) * f[:, r0] + wr * f[:, r1]  # (n_i, n_p, C)
        # Bilinear in (theta_i, phi) at every sub-cell midpoint.
        a = plane[i0][:, p0] * ((1 - wi)[:, None, None] * (1 - wp)[None, :, None])
        a += plane[i1][:, p0] * (wi[:, None, None] * (1 - wp)[None, :, None])
        a += plane[i0][:, p1] * ((1 - wi)[:, None, None] * wp[None, :, None])
        a += plane[i1][:, p1] * (wi[:, None, None] * wp[None, :, None])
        yield (a * (band * dphi)[:, None, None]).reshape(-1, channels)


def table_albedo(f: np.ndarray, theta_o_deg: np.ndarray, sub: int = 2) -> np.ndarray:
    """Albedo per channel, shape (len(theta_o_deg), C), of an isotropic table ``f``.

    ``f`` has shape (n_theta_i, n_theta_r, n_phi, C) with theta on [0, 90] deg and phi on
    [0, 180] deg at equal steps (as :func:`harness.core.brdf_io.read_brdf` returns it, folded
    tables unfolded). The viewer is on the theta_r axis, the light on theta_i.
    """
    return np.array([g.sum(axis=0) for g in _table_cells(f, theta_o_deg, sub)])


def _halfdiff_cells(f: np.ndarray, theta_o_deg: np.ndarray, rows: int = 360, cols: int = 180):
    """Per viewing angle, f cos(theta_i) dw_i of every half-vector cell of a half/difference
    table, shape (cells, C): their sum is the albedo (see :func:`halfdiff_albedo`)."""
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
    for to in np.atleast_1d(theta_o_deg):
        t = np.radians(min(float(to), 89.999))
        wo = np.array([np.sin(t), 0.0, np.cos(t)])
        d = h @ wo
        wi = 2.0 * d[:, None] * h - wo
        ok = (d > 0) & (wi[:, 2] > 0)
        wi_ok = wi[ok] / np.linalg.norm(wi[ok], axis=1, keepdims=True)
        val = halfdiff_lookup(f, wi_ok, np.broadcast_to(wo, wi_ok.shape))
        yield val * (wi_ok[:, 2] * 4.0 * d[ok] * weight[ok])[:, None]


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
    return np.array([g.sum(axis=0) for g in _halfdiff_cells(f, theta_o_deg, rows, cols)])


def channel_floor(f: np.ndarray, theta_o_deg: np.ndarray, halfdiff: bool, fine: int = 2) -> np.ndarray:
    """Per viewing angle and channel, shape (len(theta_o_deg), C): the per-sample relative spread
    of f cos / pdf left by the best sampler that draws one direction for all channels.

    With H_c = f_c cos dw / a_c per quadrature cell (each channel's integrand over its albedo,
    summing to 1), the sum of the channels' relative variances under cell probabilities P is
    sum_c sum H_c^2 / P - C, least (Cauchy-Schwarz) at P proportional to sqrt(sum_c H_c^2). Each
    channel's spread under that P is returned. Zero when the channels have one shape (a sampler
    can follow it exactly); a table whose channels carry independent measurement noise keeps
    about that noise, whatever the sampler. It bounds N independent samples per pixel at
    spread / sqrt(N); stratified samples do better only where the noise varies slowly across a
    stratum (a lobe a few table cells wide), not where a stratum holds many cells. ``fine``
    refines the quadrature (sub-cells per table cell, or half-vector rows x 360 and columns x 180)
    so that it resolves the noise.
    """
    cells = _halfdiff_cells(f, theta_o_deg, 360 * fine, 180 * fine) if halfdiff else _table_cells(f, theta_o_deg, fine)
    return np.array([shared_floor(g)[0] for g in cells])


def shared_floor(g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The core of :func:`channel_floor` for cell contributions ``g`` (cells, C), each channel's
    summing to its albedo: (each channel's relative spread, the cell probabilities P)."""
    h = np.asarray(g, dtype=np.float64)
    h = h / h.sum(axis=0)
    p = np.sqrt((h ** 2).sum(axis=1))
    p = p / p.sum()
    keep = p > 0
    spread = np.sqrt(np.maximum(0.0, (h[keep] ** 2 / p[keep, None]).sum(axis=0) - 1.0))
    return spread, p
