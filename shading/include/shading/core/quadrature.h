// Gauss-Legendre rules: an n-point rule integrates polynomials of degree 2n - 1 exactly. The
// nodes and weights are written out to 16 digits (each rule keeps the order its callers sum in).
#pragma once

namespace shading {

// 4 points on [-1, 1].
constexpr double kGaussLegendre4X[4] = {-0.8611363115940526, -0.3399810435848563, 0.3399810435848563,
                                        0.8611363115940526};
constexpr double kGaussLegendre4W[4] = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461,
                                        0.3478548451374538};

// 5 points on [-1, 1], the centre first.
constexpr double kGaussLegendre5X[5] = {0.0, -0.5384693101056831, 0.5384693101056831, -0.9061798459386640,
                                        0.9061798459386640};
constexpr double kGaussLegendre5W[5] = {0.5688888888888889, 0.4786286704993665, 0.4786286704993665,
                                        0.2369268850561891, 0.2369268850561891};

// 8 points on [0, 1] (the weights sum to 1).
constexpr double kGaussLegendre8UnitX[8] = {0.019855071751231856, 0.10166676129318664, 0.2372337950418355,
                                            0.4082826787521751,   0.5917173212478249,  0.7627662049581645,
                                            0.8983332387068134,   0.9801449282487681};
constexpr double kGaussLegendre8UnitW[8] = {0.05061426814518813, 0.11119051722668724, 0.15685332293894363,
                                            0.18134189168918100, 0.18134189168918100, 0.15685332293894363,
                                            0.11119051722668724, 0.05061426814518813};

// The integral of f over [a, b] by the 5-point rule.
template <class F>
double gauss_legendre5(const F& f, double a, double b) {
    const double c = 0.5 * (a + b), h = 0.5 * (b - a);
    double s = 0.0;
    for (int i = 0; i < 5; ++i) s += kGaussLegendre5W[i] * f(c + h * kGaussLegendre5X[i]);
    return s * h;
}

}  // namespace shading
