"""Scattering coefficients from a radial reflectance profile: fit sigma_a and sigma_s' with the dipole.

A translucent sample lit by a narrow beam (or a point) glows around the entry point with
radial exitance Rd(r) (per unit entering power, per area). Given the relative index eta,
:func:`fit_profile` finds the reduced scattering coefficient sigma_s' and the absorption
coefficient sigma_a whose dipole (Jensen et al. 2001; :class:`harness.reference.dipole_ref.Dipole`, the
numpy mirror of ``shading/include/shading/dipole.h``) best matches the profile:

* the model at each point is the dipole's Rd(r) or, for binned data (``r_edges`` given, as
  :mod:`harness.reference.mc_subsurface` tallies), the mean of Rd over each annulus (closed form);
* the unknowns are log sigma_a and log sigma_s' (both stay positive; the profile fixes them
  on a scale of decades); optionally a free log amplitude when the profile's absolute scale is
  unknown (a camera in arbitrary units): then only the profile's shape constrains them;
* residuals are (model - data) / sigma_i with the data's standard errors, or relative
  (model - data) / data when none are given (the profile spans decades);
* minimised by Levenberg-Marquardt (``scipy.optimize.least_squares``, MINPACK);
* uncertainty: the covariance s^2 (J^T J)^-1 at the optimum, s^2 = chi^2 / (n - p) (the
  residual variance; with given standard errors and a good model s^2 ~ 1), turned into
  standard errors of sigma_a and sigma_s' by the delta method (sigma_x = x sigma_log x), and
  optionally a residual bootstrap (``bootstrap=N``: refits to model + resampled residuals).

    python -m harness.tools.scatter_fit --demo       # dipole- and Monte-Carlo-generated profiles
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, field
from typing import Callable, Optional, Sequence

import numpy as np
from scipy.optimize import least_squares

from harness.reference import dipole_ref


@dataclass
class ScatterFit:
    sigma_a: float
    sigma_s_prime: float
    sigma_a_err: float            # one standard error (covariance)
    sigma_s_prime_err: float
    amplitude: float = 1.0        # free amplitude (1 when the scale is known)
    chi2: float = 0.0             # sum of squared residuals at the optimum
    dof: int = 0
    iterations: int = 0           # residual evaluations of the optimiser
    covariance_log: np.ndarray = field(default_factory=lambda: np.zeros((2, 2)))  # of (log sa, log ss')
    bootstrap: Optional[np.ndarray] = None  # (N, 2) refits (sigma_a, sigma_s') when asked

    def describe(self) -> str:
        s = (f"sigma_a = {self.sigma_a:.5g} +- {self.sigma_a_err:.2g}, "
             f"sigma_s' = {self.sigma_s_prime:.5g} +- {self.sigma_s_prime_err:.2g}")
        if self.bootstrap is not None:
            sd = self.bootstrap.std(axis=0, ddof=1)
            s += f" (bootstrap sd {sd[0]:.2g}, {sd[1]:.2g})"
        return s + f"; chi2/dof = {self.chi2 / max(self.dof, 1):.3g}"


def dipole_profile(sigma_a: float, sigma_s_prime: float, eta: float, r: np.ndarray,
                   r_edges: Optional[np.ndarray] = None) -> np.ndarray:
    """Rd at radii ``r``, or its annulus means over ``r_edges`` (len(r) + 1 edges)."""
    d = dipole_ref.Dipole(sigma_s_prime, sigma_a, eta)
    if r_edges is not None:
        return np.asarray(d.rd_annulus_mean(r_edges[:-1], r_edges[1:]), dtype=float)
    return np.asarray(d.rd(r), dtype=float)


def _least_squares(res: Callable[[np.ndarray], np.ndarray], x0: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Minimise |res(x)|^2 by Levenberg-Marquardt (scipy's MINPACK wrapper); returns
    (x, Jacobian at x, function evaluations)."""
    sol = least_squares(res, np.asarray(x0, dtype=float), method="lm", xtol=1e-12, ftol=1e-12, gtol=1e-12,
                        max_nfev=2000)
    return sol.x, sol.jac, int(sol.nfev)


def fit_profile(r: np.ndarray, rd: np.ndarray, eta: float, rd_err: Optional[np.ndarray] = None,
                r_edges: Optional[np.ndarray] = None, free_amplitude: bool = False,
                start: Optional[tuple[float, float]] = None, bootstrap: int = 0, seed: int = 1) -> ScatterFit:
    """Fit (sigma_a, sigma_s') of the dipole to a radial profile; see the module doc.

    Points with rd <= 0 (empty bins) or non-finite values are left out.
    """
    r = np.asarray(r, dtype=float)
    rd = np.asarray(rd, dtype=float)
    keep = np.isfinite(rd) & (rd > 0)
    if rd_err is not None:
        rd_err = np.asarray(rd_err, dtype=float)
        keep &= np.isfinite(rd_err) & (rd_err > 0)
    if r_edges is not None:
        r_edges = np.asarray(r_edges, dtype=float)
        lo, hi = r_edges[:-1][keep], r_edges[1:][keep]
    r, rd = r[keep], rd[keep]
    sig = rd_err[keep] if rd_err is not None else rd

    def model(x: np.ndarray, rr=r) -> np.ndarray:
        sa, ss = math.exp(x[0]), math.exp(x[1])
        d = dipole_ref.Dipole(ss, sa, eta)
        m = d.rd_annulus_mean(lo, hi) if r_edges is not None else d.rd(rr)
        return np.asarray(m, dtype=float) * (math.exp(x[2]) if free_amplitude else 1.0)

    def residuals_for(data: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        return lambda x: (model(x) - data) / sig

    # Start: a grid over (sigma_a, sigma_s') scaled to the profile's radii.
    if start is None:
        rm = float(np.median(r[r > 0])) if np.any(r > 0) else 1.0
        best = None
        for ss in np.geomspace(0.1, 100.0, 13) / rm:
            for sa in np.geomspace(1e-4, 1.0, 13) * ss:
                x = np.array([math.log(sa), math.log(ss)] + ([0.0] if free_amplitude else []))
                if free_amplitude:
                    m = model(x)
                    x[2] = math.log(max(np.sum(rd * m / sig**2) / max(np.sum(m * m / sig**2), 1e-300), 1e-300))
                c = residuals_for(rd)(x)
                c = c @ c
                if np.isfinite(c) and (best is None or c < best[0]):
                    best = (c, x)
        x0 = best[1]
    else:
        x0 = np.array([math.log(start[0]), math.log(start[1])] + ([0.0] if free_amplitude else []))
    x, J, it = _least_squares(residuals_for(rd), x0)
    res = residuals_for(rd)(x)
    chi2 = float(res @ res)
    dof = max(len(rd) - len(x), 1)
    cov = np.linalg.pinv(J.T @ J) * (chi2 / dof)
    sa, ss = math.exp(x[0]), math.exp(x[1])
    out = ScatterFit(sigma_a=sa, sigma_s_prime=ss, sigma_a_err=sa * math.sqrt(max(cov[0, 0], 0.0)),
                     sigma_s_prime_err=ss * math.sqrt(max(cov[1, 1], 0.0)),
                     amplitude=math.exp(x[2]) if free_amplitude else 1.0, chi2=chi2, dof=dof, iterations=it,
                     covariance_log=cov[:2, :2])
    if bootstrap > 0:
        rng = np.random.default_rng(seed)
        fitted = model(x)
        scaled = res  # residuals in units of sig
        boots = []
        for _ in range(bootstrap):
            data = fitted + rng.choice(scaled, size=scaled.size, replace=True) * sig
            xb, _, _ = _least_squares(residuals_for(data), x)
            boots.append([math.exp(xb[0]), math.exp(xb[1])])
        out.bootstrap = np.asarray(boots)
    return out


# ---------------------------------------------------------------- demo / report

def demo_dipole(sigma_a: float = 0.02, sigma_s_prime: float = 1.0, eta: float = 1.3, noise: float = 0.03,
                seed: int = 1, bootstrap: int = 0) -> tuple[ScatterFit, dict]:
    """A dipole profile at 40 radii (0.1 .. 30 mfp'), multiplicative Gaussian noise, fitted back."""
    st = sigma_s_prime + sigma_a
    r = np.geomspace(0.1, 30.0, 40) / st
    truth = dipole_profile(sigma_a, sigma_s_prime, eta, r)
    rng = np.random.default_rng(seed)
    data = truth * (1.0 + noise * rng.standard_normal(r.size))
    fit = fit_profile(r, data, eta, rd_err=noise * truth, bootstrap=bootstrap, seed=seed)
    return fit, {"sigma_a": sigma_a, "sigma_s_prime": sigma_s_prime, "eta": eta, "noise": noise}


def fit_diffusion_window(r: np.ndarray, rd: np.ndarray, eta: float, rd_err: Optional[np.ndarray] = None,
                         r_edges: Optional[np.ndarray] = None, r_min_mfp: float = 2.5, r_max_mfp: float = 20.0,
                         rounds: int = 4, **kw) -> ScatterFit:
    """:func:`fit_profile` on the radii where the dipole is a fair model: between ``r_min_mfp``
    and ``r_max_mfp`` reduced mean free paths 1/sigma_t' of the *fitted* medium (found by
    iterating from a fit to every point). Near the entry point single scattering and the
    dipole's source approximation dominate: measured against Monte Carlo the dipole is 20-50 %
    high at 1-1.5 mfp' and within ~5 % beyond 2.5 mfp' (alpha' = 0.98, eta = 1.3)."""
    r = np.asarray(r, dtype=float)
    fit = fit_profile(r, rd, eta, rd_err=rd_err, r_edges=r_edges, **kw)
    for _ in range(rounds):
        st = fit.sigma_a + fit.sigma_s_prime
        use = (r * st >= r_min_mfp) & (r * st <= r_max_mfp)
        if use.sum() < 4:
            break
        data = np.where(use, rd, np.nan)
        fit = fit_profile(r, data, eta, rd_err=None if rd_err is None else np.where(use, rd_err, np.nan),
                          r_edges=r_edges, start=(fit.sigma_a, fit.sigma_s_prime), **kw)
    return fit


def demo_mc(sigma_a: float = 0.05, sigma_s_prime: float = 1.0, eta: float = 1.3, n_photons: int = 20000,
            seed: int = 1) -> tuple[ScatterFit, dict]:
    """A Monte Carlo profile (harness.reference.mc_subsurface, g = 0, seeded) fitted in the diffusion
    window (:func:`fit_diffusion_window`)."""
    from harness.reference.mc_subsurface import simulate
    st = sigma_s_prime + sigma_a
    edges = np.concatenate([[0.0], np.geomspace(0.05, 40.0, 41)]) / st
    mc = simulate(sigma_s_prime, sigma_a, g=0.0, eta=eta, n_photons=n_photons, seed=seed, r_edges=edges)
    mid = 0.5 * (edges[:-1] + edges[1:])
    fit = fit_diffusion_window(mid, mc.rd_r, eta, rd_err=mc.rd_r_err, r_edges=edges)
    return fit, {"sigma_a": sigma_a, "sigma_s_prime": sigma_s_prime, "eta": eta, "photons": n_photons,
                 "seconds": mc.seconds}


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.tools.scatter_fit", description=__doc__.split("\n\n")[0])
    ap.add_argument("--demo", action="store_true", help="fit dipole- and Monte-Carlo-generated profiles")
    ap.add_argument("--photons", type=int, default=20000)
    ap.add_argument("--bootstrap", type=int, default=50)
    args = ap.parse_args(argv)
    if not args.demo:
        ap.print_help()
        return 2
    print("dipole-generated profiles (40 radii 0.1..30 mfp', 3 % noise, eta 1.3):")
    for sa, ss in ((0.02, 1.0), (0.1, 2.0), (0.005, 0.5)):
        fit, t = demo_dipole(sa, ss, bootstrap=args.bootstrap)
        print(f"  truth sigma_a = {sa:g}, sigma_s' = {ss:g}:  {fit.describe()}")
    print(f"Monte Carlo profiles ({args.photons} photons, seed 1, g = 0, eta 1.3, bins 2.5..20 fitted mfp'):")
    for sa, ss in ((0.02, 1.0), (0.1, 1.0), (0.005, 1.0)):
        fit, t = demo_mc(sa, ss, n_photons=args.photons)
        print(f"  truth sigma_a = {sa:g}, sigma_s' = {ss:g}:  {fit.describe()}  [MC {t['seconds']:.1f} s]")
    return 0


if __name__ == "__main__":
    sys.exit(main())
