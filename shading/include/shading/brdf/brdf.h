// The BRDF interface every model implements, the local-frame helpers the models share, and
// pov_weight(): how a BRDF value becomes POV-Ray's light contribution.
//
// Convention (vec.h): local frame, normal +z, tangent +x; f(wo, wi) in 1/sr EXCLUDING
// cos(theta_i); wo toward the viewer, wi toward the light; f = 0 when either z <= 0; never
// NaN, Inf or negative. One file per model in src/brdf/; make_brdf() (model_spec.h) builds
// them from spec strings. Equations, parameters and limits: shading/MODELS.md.
#pragma once

#include <memory>
#include <string>

#include "shading/core/vec.h"

namespace shading {

class SpecWriter;  // spec_args.h

// What a model may compute once for a viewer direction and reuse for every light at one
// shading point (FinishView), e.g. the Smith masking of wo. Opaque to everyone but the model.
struct BrdfViewCache {
    double v[2] = {0, 0};
    bool valid = false;
};

class Brdf {
public:
    virtual ~Brdf() = default;
    // The BRDF under the convention above, for every pair of unit vectors.
    virtual Rgb f(const Vec3& wo, const Vec3& wi) const = 0;
    // True if the model depends on the azimuth of the tangent frame (needs +x).
    virtual bool anisotropic() const { return false; }
    // Short human-readable description with parameters, e.g. "lambert(rho=0.5)".
    virtual std::string describe() const = 0;
    // The make_brdf() spec of this model (model_spec.h), written by write_spec(). With
    // digits = 0 it parses back into a model with the same f, sample and pdf to the bit;
    // digits > 0 rounds every number to that many significant digits. Empty for BRDFs
    // make_brdf() does not build (tables, subsurface).
    std::string spec(int digits = 0) const;
    // The model's name and keys; every model make_brdf() builds writes them.
    virtual void write_spec(SpecWriter& w) const { (void)w; }

    // Albedo of the Lambertian base the model includes (f contains base / pi), per channel;
    // zero for models without one. The rest, f - base/pi, is the model's glossy part.
    virtual Rgb lambert_base() const { return Rgb(0.0); }

    // Importance sampling of wi for light reflected toward wo: sample() maps (u1, u2) in
    // [0,1)^2 to a unit wi with density pdf(wo, wi) per solid angle, or returns the zero
    // vector (no sample: the direction fell below the surface; pdf() integrates to the
    // probability of a valid sample). The default is a model-agnostic mixture (1/4 each):
    // cosine-weighted, and cos^e lobes about the mirror direction of wo with e = 30, 300,
    // 3000 (lobes ~15 to ~1.5 deg wide); it covers the whole hemisphere, so f cos / pdf is
    // an unbiased estimator for any model, and the lobes keep its variance moderate for
    // glossy and near-mirror reflection.
    virtual Vec3 sample(const Vec3& wo, double u1, double u2) const;
    virtual double pdf(const Vec3& wo, const Vec3& wi) const;
    // The same for the glossy part only (what a finish's `samples` traces). Defaults to
    // sample()/pdf(); Microfacet and Ward sample their specular lobe alone (the others keep
    // the default mixture: unbiased, with some rays spent on the base's directions).
    virtual Vec3 sample_glossy(const Vec3& wo, double u1, double u2) const { return sample(wo, u1, u2); }
    virtual double pdf_glossy(const Vec3& wo, const Vec3& wi) const { return pdf(wo, wi); }

    // Per-viewer precomputation: prepare_view(wo) once, then f_view(wo, wi, cache) for each
    // light, which must equal f(wo, wi) to the bit. The default keeps nothing.
    virtual void prepare_view(const Vec3& wo, BrdfViewCache* cache) const {
        (void)wo;
        cache->valid = false;
    }
    virtual Rgb f_view(const Vec3& wo, const Vec3& wi, const BrdfViewCache& cache) const {
        (void)cache;
        return f(wo, wi);
    }
};

// Directional albedo a(theta_o) = integral of f cos over the hemisphere, wo at azimuth 0 (along
// the tangent), by multiple importance sampling over stratified grids of five components: the
// four of the default sampler and the model's own sampler, combined with the balance
// heuristic. The Lambertian base is added exactly. Accuracy: MODELS.md section 6.
Rgb quadrature_albedo(const Brdf& b, double theta_o);

// The default sampler of Brdf::sample()/pdf(): exponents of its mirror lobes.
constexpr double kGenericLobeExponents[3] = {30.0, 300.0, 3000.0};
// A direction with density (e+1)/(2 pi) cos^e about the unit `axis` (e = 1 about the normal
// is cosine-weighted hemisphere sampling), and that density at w (0 behind the axis).
Vec3 sample_cosine_power(const Vec3& axis, double e, double u1, double u2);
double cosine_power_pdf(const Vec3& axis, double e, const Vec3& w);
// Largest double below 1, so u in [0,1) stays below 1 after scaling.
constexpr double kOneMinusEps = 1.0 - 0x1.0p-53;

using BrdfPtr = std::shared_ptr<const Brdf>;

// ---------------------------------------------------------------- helpers the models share

// Cosines below this are clamped where they divide: a direction within 1e-12 rad of the
// horizon. The models' 1/cos factors would otherwise overflow to Inf for denormal cosines;
// pov_weight() multiplies by cos_i, so nothing a renderer shows changes.
constexpr double kCosFloor = 1e-12;
// Half vector of a reflection pair; wo + wi != 0 whenever both are above the surface.
inline Vec3 half_vector(const Vec3& wo, const Vec3& wi) { return normalize(wo + wi); }
// Mirror w about the unit vector h: 2 (w.h) h - w.
inline Vec3 reflect_about(const Vec3& w, const Vec3& h) { return h * (2.0 * dot(w, h)) - w; }
// Mirror direction of w about the normal +z.
inline Vec3 mirror_z(const Vec3& w) { return {-w.x, -w.y, w.z}; }
// A Lambertian base of albedo rho: f = rho / pi.
inline Rgb lambert_f(const Rgb& rho) { return rho * kInvPi; }

// ---------------------------------------------------------------- POV-Ray's convention

// POV-Ray's light contribution factor for one light of colour c:
// pixel += pov_weight(...) * c. POV's pixel values are pi x radiance and its light
// colour is irradiance at normal incidence, so radiance f*cos*E becomes pi*f*cos.
// A Lambert BRDF rho/pi thus contributes rho*cos, exactly like `diffuse rho`. (The finish
// layer's table fast path, detail::table_light_weight in finish.h, applies the same factor.)
inline Rgb pov_weight(const Brdf& brdf, const Vec3& wo, const Vec3& wi) {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    return brdf.f(wo, wi) * (kPi * wi.z);
}
// The same through a prepared viewer (Brdf::prepare_view): the same bits.
inline Rgb pov_weight(const Brdf& brdf, const Vec3& wo, const Vec3& wi, const BrdfViewCache& cache) {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    return brdf.f_view(wo, wi, cache) * (kPi * wi.z);
}

}  // namespace shading
