// The default importance sampler every Brdf inherits, and the directional albedo by
// quadrature over it (brdf.h).
#include "shading/brdf/brdf.h"
#include "shading/brdf/spec_args.h"

#include <algorithm>
#include <cmath>

namespace shading {

std::string Brdf::spec(int digits) const {
    SpecWriter w(digits);
    write_spec(w);
    return w.str();
}

Vec3 sample_cosine_power(const Vec3& axis, double e, double u1, double u2) {
    // Inverse CDF of (e+1) cos^e sin over [0, pi/2]: cos theta = (1 - u1)^(1/(e+1)).
    const double c = std::pow(1.0 - u1, 1.0 / (e + 1.0));
    const double s = std::sqrt(std::max(0.0, 1.0 - c * c)), phi = 2.0 * kPi * u2;
    return Frame::from_normal(axis).to_world(Vec3(s * std::cos(phi), s * std::sin(phi), c));
}

double cosine_power_pdf(const Vec3& axis, double e, const Vec3& w) {
    const double c = dot(axis, w);
    return c > 0 ? (e + 1.0) / (2.0 * kPi) * std::pow(c, e) : 0.0;
}

namespace {
// The four equally weighted components of the default sampler: (axis, exponent).
struct Component {
    Vec3 axis;
    double e;
};
void generic_components(const Vec3& wo, Component out[4]) {
    const Vec3 mirror(-wo.x, -wo.y, wo.z);
    out[0] = {Vec3(0, 0, 1), 1.0};  // cosine-weighted hemisphere: (1+1)/(2 pi) cos = cos/pi
    for (int i = 0; i < 3; ++i) out[i + 1] = {mirror, kGenericLobeExponents[i]};
}
}  // namespace

Vec3 Brdf::sample(const Vec3& wo, double u1, double u2) const {
    if (!(wo.z > 0)) return {};  // viewer below the surface: nothing reflects toward it
    Component comp[4];
    generic_components(wo, comp);
    const double x = std::min(u1, kOneMinusEps) * 4.0;
    const int k = std::min(int(x), 3);
    const Vec3 wi = sample_cosine_power(comp[k].axis, comp[k].e, std::min(x - k, kOneMinusEps), u2);
    return wi.z > 0 ? wi : Vec3();  // a lobe's tail below the horizon: no sample
}

double Brdf::pdf(const Vec3& wo, const Vec3& wi) const {
    if (!(wo.z > 0) || !(wi.z > 0)) return 0.0;
    Component comp[4];
    generic_components(wo, comp);
    double p = 0.0;
    for (const Component& c : comp) p += cosine_power_pdf(c.axis, c.e, wi);
    return 0.25 * p;
}

// The four components of the default sampler cover any lobe; the model's own sampler adds the
// microfacet D's or Ward's long tails. Equal counts, balance heuristic: each sample weighs
// f cos / the mean of the five pdfs. Accuracy: MODELS.md 6.
Rgb quadrature_albedo(const Brdf& b, double theta_o) {
    constexpr int n = 48;  // strata per axis and component
    const Vec3 wo(std::sin(theta_o), 0.0, std::cos(theta_o));
    const Vec3 mirror(-wo.x, 0.0, wo.z);
    const Vec3 axes[4] = {Vec3(0, 0, 1), mirror, mirror, mirror};
    const double exps[4] = {1.0, kGenericLobeExponents[0], kGenericLobeExponents[1], kGenericLobeExponents[2]};
    // The default mixture's pdf is the mean of its four components (Brdf::pdf, not overridden).
    auto mixture = [&](const Vec3& wi) { return 0.8 * b.Brdf::pdf(wo, wi) + 0.2 * b.pdf(wo, wi); };
    // The Lambertian base integrates to its albedo exactly: only the rest is integrated, so a
    // small glossy part on a large base keeps its relative accuracy.
    const Rgb base = b.lambert_base(), base_f = base * kInvPi;
    Rgb sum;
    for (int comp = 0; comp < 5; ++comp)
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                const double u1 = (i + 0.5) / n, u2 = (j + 0.5) / n;
                const Vec3 wi = comp < 4 ? sample_cosine_power(axes[comp], exps[comp], u1, u2) : b.sample(wo, u1, u2);
                if (!(wi.z > 0)) continue;  // below the surface (or no sample): contributes 0
                const double p = mixture(wi);
                if (p > 0) sum += (b.f(wo, wi) - base_f) * (wi.z / (5.0 * p));
            }
    return sum * (1.0 / (n * n)) + base;
}

}  // namespace shading
