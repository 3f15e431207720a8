// microfacet: the D, G and F terms, their sampling, and the microfacet BRDF in the survey
// (rho_s DGF / (pi N.V N.L)) or the normalised Cook-Torrance form (rho_s DGF / (4 N.V N.L)),
// over an optional Lambertian base (MODELS.md 2.5 and 3). Reciprocal in both forms; the
// normalised form's albedo stays <= 1 (the survey form's D is unnormalised); samples D.
#include "shading/brdf/microfacet.h"

#include "shading/brdf/model_spec.h"
#include "shading/brdf/spec_args.h"
#include "shading/core/format.h"
#include "shading/core/quadrature.h"

#include <algorithm>
#include <sstream>

namespace shading {

namespace {

// Gaussian D's alpha-density without the constant: exp(-(a n2)^2) cos a sin a.
struct GaussianIntegrand {
    double n2;
    double operator()(double a) const { return std::exp(-sqr(a * n2)) * std::cos(a) * std::sin(a); }
};
constexpr int kGaussSegments = 256;
// Upper limit of the Gaussian's alpha integral: beyond a = 8/n2 the integrand is below
// exp(-64) ~ 1.6e-28 of its scale, so the truncation is invisible in double precision.
double gaussian_amax(double n2) { return std::min(kPi / 2, 8.0 / n2); }

using detail::fmt;

}  // namespace

// ---------------------------------------------------------------- Gaussian D

// Tabulated CDF in alpha of the Gaussian D's density, for its normalisation and for
// inverting the CDF when sampling.
struct NormalDistribution::GaussianTable {
    GaussianIntegrand f;
    double amax = 0, total = 0;
    std::vector<double> cdf;  // kGaussSegments + 1 partial integrals, cdf[0] = 0

    explicit GaussianTable(double n2) : f{n2}, amax(gaussian_amax(n2)), cdf(kGaussSegments + 1, 0.0) {
        for (int i = 0; i < kGaussSegments; ++i) cdf[i + 1] = cdf[i] + gauss_legendre5(f, edge(i), edge(i + 1));
        total = cdf[kGaussSegments];
    }
    double edge(int i) const { return amax * i / kGaussSegments; }

    // alpha with CDF(alpha) = u * total: bracket from the table, then safeguarded Newton
    // on the exact integral (so sample_h agrees with normalized() to ~1e-15).
    double invert(double u) const {
        double target = u * total;
        int i = int(std::upper_bound(cdf.begin(), cdf.end(), target) - cdf.begin()) - 1;
        i = std::clamp(i, 0, kGaussSegments - 1);
        double lo = edge(i), hi = edge(i + 1), base = edge(i);
        double span = cdf[i + 1] - cdf[i];
        double a = span > 0 ? lo + (hi - lo) * std::clamp((target - cdf[i]) / span, 0.0, 1.0) : lo;
        for (int it = 0; it < 50; ++it) {
            double g = cdf[i] + gauss_legendre5(f, base, a) - target;
            if (std::abs(g) <= 1e-15 * total) break;
            if (g > 0) hi = a; else lo = a;
            if (hi - lo <= 1e-16 * amax) break;
            double d = f(a);
            double next = d > 0 ? a - g / d : 0.5 * (lo + hi);
            // A Newton step leaving the bracket (flat integrand near a = 0): bisect instead.
            if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
            a = next;
        }
        return a;
    }
};

double gaussian_norm(double n2) {
    GaussianIntegrand f{n2};
    double amax = gaussian_amax(n2), total = 0.0;
    for (int i = 0; i < kGaussSegments; ++i)
        total += gauss_legendre5(f, amax * i / kGaussSegments, amax * (i + 1) / kGaussSegments);
    return 1.0 / (2.0 * kPi * total);
}

// ---------------------------------------------------------------- exact Smith table

SmithLambdaTable::SmithLambdaTable(const std::function<double(double)>& d, double m_scale, double theta_max)
    : m_(m_scale), g_(kNodes + 1, 0.0) {
    for (int i = 0; i < kNodes; ++i) {  // g_[kNodes]: a = Inf, theta_o = 0, Lambda = 0
        double u = i * (kPi / 2) / kNodes;
        double a = std::tan(u);
        double theta_o = std::atan2(1.0, m_ * a);  // cot(theta_o) = m a
        double so = std::sin(theta_o), co = std::cos(theta_o);
        // Microfacets facing away from wo have theta_h > pi/2 - theta_o.
        double t0 = kPi / 2 - theta_o;
        if (t0 >= theta_max) continue;  // D negligible there: Lambda = 0
        double len = theta_max - t0;
        // phi_h integral of max(0, -(A + B cos phi)), A = cos_o cos_h, B = sin_o sin_h:
        // 2 B sin(phi0) - 2 A (pi - phi0), phi0 = acos(-A/B), zero when B <= A.
        auto integrand = [&](double t) {
            double th = t0 + len * t * t;  // t^2 map: dense where the kink at t0 starts
            double A = co * std::cos(th), B = so * std::sin(th);
            if (B <= A) return 0.0;
            double phi0 = safe_acos(-A / B);
            double neg = 2.0 * B * std::sin(phi0) - 2.0 * A * (kPi - phi0);
            return d(std::cos(th)) * std::sin(th) * std::max(0.0, neg) * 2.0 * len * t;
        };
        const int segs = 32;
        double y = 0.0;  // = Lambda cos(theta_o)
        for (int k = 0; k < segs; ++k) y += gauss_legendre5(integrand, double(k) / segs, double(k + 1) / segs);
        // g = Lambda a = (Lambda cos_o) / (m sin_o): no division by cos_o at grazing.
        g_[i] = y / (m_ * so);
    }
}

double SmithLambdaTable::lambda(const Vec3& w) const {
    double s2 = sin2_theta(w);
    if (s2 == 0.0) return 0.0;  // along the normal nothing is masked
    double a = std::abs(w.z) / (std::sqrt(s2) * m_);
    if (a == 0.0) return std::numeric_limits<double>::infinity();  // grazing: fully masked
    double x = std::atan(a) / (kPi / 2) * kNodes;
    int i = std::min(int(x), kNodes - 1);
    double t = x - i;
    return ((1.0 - t) * g_[i] + t * g_[i + 1]) / a;
}

// ---------------------------------------------------------------- sampling

Vec3 sample_blinn(double n, double u1, double u2) {
    double c = std::pow(1.0 - u1, 1.0 / (n + 2.0));  // 1 - u1 in (0, 1]: theta grows with u1
    return spherical_direction(safe_acos(c), 2.0 * kPi * u2);
}

Vec3 sample_ggx(double alpha, double u1, double u2) {
    u1 = std::min(u1, kOneMinusEps);  // u1 -> 1 would give tan = Inf
    double t2 = alpha * alpha * u1 / (1.0 - u1);
    double c = 1.0 / std::sqrt(1.0 + t2);
    return spherical_direction(safe_acos(c), 2.0 * kPi * u2);
}

Vec3 sample_beckmann_aniso(double ax, double ay, double u1, double u2) {
    u1 = std::min(u1, kOneMinusEps);  // log(1 - u1) finite
    double r = std::sqrt(-std::log1p(-u1));
    double phi = 2.0 * kPi * u2;
    double sx = ax * r * std::cos(phi), sy = ay * r * std::sin(phi);
    return normalize(Vec3(-sx, -sy, 1.0));
}

// ---------------------------------------------------------------- NormalDistribution

NormalDistribution::NormalDistribution(DKind kind, double param) : kind_(kind), param_(param) {
    if (kind_ == DKind::Gaussian) {
        table_ = std::make_shared<const GaussianTable>(param_);
        norm_ = 1.0 / (2.0 * kPi * table_->total);
    }
    if (kind_ == DKind::Blinn || kind_ == DKind::Gaussian) {
        double m = m_equivalent();
        // Both lobes fall below exp(-64) of their peak beyond theta_h = 8 m (MODELS.md).
        double theta_max = std::min(kPi / 2, 8.0 * m);
        NormalDistribution self = *this;  // copy without smith_ (not yet set)
        smith_ = std::make_shared<const SmithLambdaTable>([self](double c) { return self.normalized(c); }, m,
                                                           theta_max);
    }
}

NormalDistribution NormalDistribution::from_m(DKind kind, double m) {
    double native = m;
    switch (kind) {
        case DKind::Blinn: native = blinn_n_from_m(m); break;
        case DKind::Gaussian: native = gaussian_n2_from_m(m); break;
        case DKind::TrowbridgeReitz: native = tr_alpha_from_m(m); break;
        case DKind::Beckmann: break;
    }
    NormalDistribution d(kind, native);
    d.given_m_ = m;
    return d;
}

double NormalDistribution::m_equivalent() const {
    switch (kind_) {
        case DKind::Blinn: return m_from_blinn_n(param_);
        case DKind::Gaussian: return m_from_gaussian_n2(param_);
        case DKind::TrowbridgeReitz: return param_;
        case DKind::Beckmann: break;
    }
    return param_;
}

const char* NormalDistribution::name() const {
    switch (kind_) {
        case DKind::Blinn: return "blinn";
        case DKind::Gaussian: return "gaussian";
        case DKind::TrowbridgeReitz: return "tr";
        case DKind::Beckmann: break;
    }
    return "beckmann";
}

const char* NormalDistribution::native_key() const {
    switch (kind_) {
        case DKind::Blinn: return "n1";
        case DKind::Gaussian: return "n2";
        case DKind::TrowbridgeReitz: return "n3";
        case DKind::Beckmann: break;
    }
    return "m";
}

double NormalDistribution::survey(double cos_h) const {
    switch (kind_) {
        case DKind::Blinn: return d1_blinn(cos_h, param_);
        case DKind::Gaussian: return d2_gaussian(cos_h, param_);
        case DKind::TrowbridgeReitz: return d3_trowbridge_reitz(cos_h, param_);
        case DKind::Beckmann: break;
    }
    return d4_beckmann(cos_h, param_);
}

double NormalDistribution::normalized(double cos_h) const {
    switch (kind_) {
        case DKind::Blinn: return d_blinn(cos_h, param_);
        case DKind::Gaussian: return norm_ * d2_gaussian(cos_h, param_);
        case DKind::TrowbridgeReitz: return d_trowbridge_reitz(cos_h, param_);
        case DKind::Beckmann: break;
    }
    return d_beckmann(cos_h, param_);
}

double NormalDistribution::smith_lambda(const Vec3& w) const {
    if (kind_ == DKind::TrowbridgeReitz) return smith_lambda_ggx(w, param_);
    if (smith_) return smith_->lambda(w);
    // Beckmann at a = cot(theta) / m >= 6: Lambda < 1.5e-19, and the closed form evaluated in
    // double stays below 2^-54 in magnitude for every a >= 5.506 (scanned to a = 30 in steps of
    // 1e-7; from a ~ 26.5 both terms underflow to 0). Then 1 + Lambda == 1 exactly, so G and
    // G1 keep their bits while skipping the closed form's exp, erfc, square root and divisions
    // (z^2 > 36 m^2 sin^2: a > 6 without the root, rounding far inside the margin to 5.506).
    if (sqr(w.z) > 36.0 * sqr(param_) * sin2_theta(w)) return 0.0;
    return smith_lambda_beckmann(w, param_);
}

double NormalDistribution::smith_lambda_beckmann_equivalent(const Vec3& w) const {
    return smith_lambda_beckmann(w, m_equivalent());
}

Vec3 NormalDistribution::sample_h(double u1, double u2) const {
    switch (kind_) {
        case DKind::Blinn: return sample_blinn(param_, u1, u2);
        case DKind::Gaussian: return spherical_direction(table_->invert(u1), 2.0 * kPi * u2);
        case DKind::TrowbridgeReitz: return sample_ggx(param_, u1, u2);
        case DKind::Beckmann: break;
    }
    return sample_beckmann_aniso(param_, param_, u1, u2);
}

// ---------------------------------------------------------------- Fresnel term

Rgb FresnelTerm::eval(double cos_d) const {
    switch (kind) {
        case FKind::None: return Rgb(1.0);
        case FKind::Dielectric: return Rgb(fresnel_dielectric(cos_d, eta));
        case FKind::Conductor: return fresnel_conductor(cos_d, n, k);
        case FKind::Schlick: break;
    }
    return fresnel_schlick(cos_d, f0);
}

std::string FresnelTerm::describe() const {
    switch (kind) {
        case FKind::None: return "f=none";
        case FKind::Dielectric: return "f=dielectric eta=" + fmt(eta);
        case FKind::Conductor: return "f=conductor n=" + fmt(n) + " k=" + fmt(k);
        case FKind::Schlick: break;
    }
    return "f=schlick f0=" + fmt(f0);
}

void FresnelTerm::write_spec(SpecWriter& w) const {
    switch (kind) {
        case FKind::None: w.word("f", "none"); return;
        case FKind::Dielectric: w.word("f", "dielectric").number("eta", eta); return;
        case FKind::Conductor: w.word("f", "conductor").rgb("n", n).rgb("k", k); return;
        case FKind::Schlick: break;
    }
    w.word("f", "schlick").rgb("f0", f0);
}

// ---------------------------------------------------------------- Microfacet

double Microfacet::geometry(const Vec3& wo, const Vec3& wi, const Vec3& h) const {
    if (g == GKind::VCavity) return g_vcavity(h.z, wo.z, wi.z, dot(wo, h));
    return g_smith(d.smith_lambda(wo), d.smith_lambda(wi));
}

Rgb Microfacet::f(const Vec3& wo, const Vec3& wi) const { return f_lambda(wo, wi, nullptr); }

void Microfacet::prepare_view(const Vec3& wo, BrdfViewCache* cache) const {
    cache->valid = g == GKind::Smith && wo.z > 0;
    if (cache->valid) cache->v[0] = d.smith_lambda(wo);
}

Rgb Microfacet::f_view(const Vec3& wo, const Vec3& wi, const BrdfViewCache& cache) const {
    return f_lambda(wo, wi, cache.valid ? &cache.v[0] : nullptr);
}

Rgb Microfacet::f_lambda(const Vec3& wo, const Vec3& wi, const double* lambda_o) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);  // below the surface: no reflection
    Rgb diffuse = kd * kInvPi;
    Vec3 h = half_vector(wo, wi);  // wo.z + wi.z > 0, so wo + wi != 0
    double vh = dot(wo, h);        // = dot(wi, h) > 0
    double G = lambda_o && g == GKind::Smith ? g_smith(*lambda_o, d.smith_lambda(wi)) : geometry(wo, wi, h);
    // Both cosines divide. f is finite for every pair with positive cosines; away from the
    // mirror pair G also vanishes with the smaller cosine. At the grazing mirror pair V-cavity
    // G -> 1 (V.H -> N.V there), so f ~ D / (4 cos^2) and pi f cos_i ~ 1/cos: the V-cavity
    // model's own grazing peak over a vanishing solid angle (albedo stays bounded; Smith G
    // goes to 0 there instead). kCosFloor only keeps denormal cosines from overflowing.
    double nv = std::max(wo.z, kCosFloor), nl = std::max(wi.z, kCosFloor);
    double s;
    if (form == MicrofacetForm::Survey)
        s = d.survey(h.z) * G / (kPi * nv * nl);  // i = rho_s D G F / (N.V); f = i / (pi N.L)
    else
        s = d.normalized(h.z) * G / (4.0 * nv * nl);  // Cook-Torrance: D G F / (4 N.L N.V)
    return diffuse + rho_s * fresnel.eval(vh) * s;
}

double Microfacet::specular_probability() const { return lobe_probability(rho_s, kd); }

Vec3 Microfacet::sample(const Vec3& wo, double u1, double u2) const {
    return sample_mix(wo, u1, u2, specular_probability());
}
Vec3 Microfacet::sample_glossy(const Vec3& wo, double u1, double u2) const { return sample_mix(wo, u1, u2, 1.0); }
Vec3 Microfacet::sample_mix(const Vec3& wo, double u1, double u2, double ps) const {
    return sample_lobe_or_cosine(wo, u1, u2, ps, [this](double a, double b) { return d.sample_h(a, b); });
}
double Microfacet::pdf(const Vec3& wo, const Vec3& wi) const { return pdf_mix(wo, wi, specular_probability()); }
double Microfacet::pdf_glossy(const Vec3& wo, const Vec3& wi) const { return pdf_mix(wo, wi, 1.0); }
double Microfacet::pdf_mix(const Vec3& wo, const Vec3& wi, double ps) const {
    return pdf_lobe_or_cosine(wo, wi, ps, [this](const Vec3& h) { return d.normalized(h.z) * h.z; });
}

std::string Microfacet::describe() const {
    std::string s = "microfacet(form=";
    s += form == MicrofacetForm::Survey ? "survey" : "normalized";
    s += std::string(" d=") + d.name() + " param=" + fmt(d.param()) + " (m=" + fmt(d.m_equivalent()) + ")";
    s += g == GKind::VCavity ? " g=vcavity " : " g=smith ";
    s += fresnel.describe() + " rho_s=" + fmt(rho_s) + " kd=" + fmt(kd) + ")";
    return s;
}


// ---------------------------------------------------------------- spec and registration

namespace {
const SpecKey kForm{"form", "survey|normalized", "survey rho_s DGF/(pi N.V N.L) or normalised rho_s DGF/(4 N.V N.L)"};
const SpecKey kD{"d", "blinn|gaussian|tr|beckmann", "normal distribution"};
const SpecKey kM{"m", "<x>", "Beckmann-equivalent roughness, mapped per d", 1e-4, 1};
const SpecKey kN1{"n1", "<x>", "d=blinn native exponent (instead of m)", 0, 1e9};
const SpecKey kN2{"n2", "<x>", "d=gaussian native width (instead of m)", 0.1, 1e5};
const SpecKey kN3{"n3", "<x>", "d=tr native alpha (instead of m)", 1e-4, 1};
const SpecKey kG{"g", "vcavity|smith", "masking-shadowing (smith: exact height-correlated Smith for every d)"};
const SpecKey kF{"f", "none|dielectric|conductor|schlick", "Fresnel term"};
const SpecKey kEta{"eta", "<x>", "f=dielectric: n_inside/n_outside", 0.01, 10};
const SpecKey kN{"n", "<rgb>", "f=conductor (required): real index", 0.01, 20};
const SpecKey kK{"k", "<rgb>", "f=conductor (required): extinction", 0, 20};
const SpecKey kF0{"f0", "<rgb>", "f=schlick: normal-incidence reflectance", 0, 1};
const SpecKey kRhoS{"rho_s", "<rgb>", "specular scale", 0, 1, " (survey: [0,100])"};
const SpecKey kKd{"kd", "<rgb>", "Lambertian base", 0, 1, "; normalized: kd+rho_s <= 1"};

const char* g_name(GKind g) { return g == GKind::VCavity ? "vcavity" : "smith"; }

std::string microfacet_keys() {
    const Microfacet d;
    return help_line(kForm, d.form == MicrofacetForm::Survey ? "survey" : "normalized") + help_line(kD, d.d.name()) +
           help_line(kM, fmt(d.d.m_equivalent())) + help_line(kN1, "") + help_line(kN2, "") + help_line(kN3, "") +
           help_line(kG, g_name(d.g)) + help_line(kF, "none") + help_line(kEta, fmt(d.fresnel.eta)) +
           help_line(kN, "") + help_line(kK, "") + help_line(kF0, fmt(d.fresnel.f0)) + help_line(kRhoS, fmt(d.rho_s)) +
           help_line(kKd, fmt(d.kd));
}

BrdfPtr make_microfacet(SpecArgs& a) {
    auto b = std::make_shared<Microfacet>();
    const std::string default_d = b->d.name();
    const double default_m = b->d.m_equivalent();
    bool survey = a.word(kForm.name, b->form == MicrofacetForm::Survey ? "survey" : "normalized",
                         {"survey", "normalized"}) == "survey";
    b->form = survey ? MicrofacetForm::Survey : MicrofacetForm::Normalized;

    std::string d = a.word(kD.name, default_d, {"blinn", "gaussian", "tr", "beckmann"});
    DKind kind = d == "blinn" ? DKind::Blinn
                 : d == "gaussian" ? DKind::Gaussian
                 : d == "tr" ? DKind::TrowbridgeReitz
                             : DKind::Beckmann;
    // Roughness: m (Beckmann-equivalent, mapped per D) or the D's native parameter.
    const SpecKey* native = kind == DKind::Blinn ? &kN1 : kind == DKind::Gaussian ? &kN2 : kind == DKind::TrowbridgeReitz ? &kN3 : nullptr;
    for (const SpecKey* k : {&kN1, &kN2, &kN3})
        if (k != native && a.has(k->name)) spec_error(a.where(k->name) + "not a parameter of d=" + d);
    if (native && a.has(native->name)) {
        if (a.has(kM.name)) spec_error(a.where(kM.name) + "give either m or " + native->name + ", not both");
        b->d = NormalDistribution(kind, a.number(*native, 0));
    } else {
        b->d = NormalDistribution::from_m(kind, a.number(kM, default_m));
    }

    std::string g = a.word(kG.name, g_name(b->g), {"vcavity", "smith"});
    b->g = g == "vcavity" ? GKind::VCavity : GKind::Smith;

    std::string f = a.word(kF.name, "none", {"none", "dielectric", "conductor", "schlick"});
    if (f != "dielectric") a.forbid({kEta.name}, "only used with f=dielectric");
    if (f != "conductor") a.forbid({kN.name, kK.name}, "only used with f=conductor");
    if (f != "schlick") a.forbid({kF0.name}, "only used with f=schlick");
    if (f == "dielectric") {
        b->fresnel.kind = FKind::Dielectric;
        b->fresnel.eta = a.number(kEta, b->fresnel.eta);
    } else if (f == "conductor") {
        b->fresnel.kind = FKind::Conductor;
        b->fresnel.n = a.rgb(kN, b->fresnel.n, true);
        b->fresnel.k = a.rgb(kK, b->fresnel.k, true);
    } else if (f == "schlick") {
        b->fresnel.kind = FKind::Schlick;
        b->fresnel.f0 = a.rgb(kF0, b->fresnel.f0);
    }

    b->kd = a.rgb(kKd, b->kd);
    b->rho_s = a.rgb(kRhoS.name, b->rho_s, kRhoS.lo, survey ? 100 : kRhoS.hi);
    if (!survey) a.check_sum("kd", b->kd, "rho_s", b->rho_s);
    return b;
}
}  // namespace

// The form only when it is survey; m when the D was built from m, else its native parameter.
void Microfacet::write_spec(SpecWriter& w) const {
    w.model("microfacet");
    if (form == MicrofacetForm::Survey) w.word(kForm.name, "survey");
    w.word(kD.name, d.name()).word(kG.name, g_name(g));
    if (d.given_m() > 0)
        w.number(kM.name, d.given_m());
    else
        w.number(d.native_key(), d.param());
    fresnel.write_spec(w);
    w.rgb(kKd.name, kd).rgb(kRhoS.name, rho_s);
}

ModelEntry microfacet_model() {
    ModelEntry m;
    m.name = "microfacet";
    m.summary = "microfacet D G F, survey form rho_s DGF/(pi N.V N.L) or normalised rho_s DGF/(4 N.V N.L), + kd/pi";
    m.keys = microfacet_keys;
    m.make = make_microfacet;
    // The survey form's D is unnormalised (peak 1, or 1/m^2): its albedo is not bounded.
    m.examples = {{"microfacet d=beckmann m=0.3 f=dielectric eta=1.5 kd=0.3 rho_s=0.6"},
                  {"microfacet d=blinn m=0.2 g=vcavity f=schlick f0=0.1 kd=0.2 rho_s=0.7"},
                  {"microfacet d=gaussian n2=6 f=conductor n=0.2,0.9,1.1 k=3.6,2.4,1.9"},
                  {"microfacet d=tr n3=0.25 kd=0.4 rho_s=0.6"},
                  {"microfacet d=blinn n1=50"},
                  {"microfacet d=gaussian m=0.35 g=vcavity"},
                  {"microfacet form=survey d=tr m=0.2 g=vcavity rho_s=2 kd=0.1", false}};
    // Closed-form D are cheap; the tabulated Smith Lambda (Blinn, Gaussian) and the
    // Gaussian's acos cost more.
    m.costs = {{"microfacet d=blinn", 1.15},
               {"microfacet d=tr", 1.15},
               {"microfacet d=beckmann", 1.20},
               {"microfacet d=gaussian", 1.30}};
    return m;
}

}  // namespace shading
