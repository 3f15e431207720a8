// sstool: build, inspect and evaluate the exact subsurface profile tables (.ssp), and run the
// library's transport Monte Carlo directly. The logic lives in the shading library
// (transport_mc.h, ss_profile.h); this file is argument handling and printing.
// Exit status: 0 ok, 1 failure (bad file, failed build), 2 usage.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "cli_options.h"
#include "shading/subsurface/dipole.h"
#include "shading/subsurface/ss_profile.h"
#include "shading/tables/table.h"  // write_file_bytes
#include "shading/subsurface/transport_mc.h"

using namespace shading;

namespace {

using shading_tools::UsageError;

const char* kUsage =
    "usage: sstool COMMAND [options]\n"
    "  build -o FILE [--if-stale] [--g LIST] [--eta LIST] [--thickness LIST] [--photons N]\n"
    "        [--short-photons N] [--albedos N] [--angle-nodes N] [--seed S] [--threads T]\n"
    "        [--quiet | --verbose]\n"
    "        build the exact-profile tables (defaults: the grid `make brdf-data` ships, see\n"
    "        shading/DIPOLE.md; --angle-nodes: inside-radiance samples per exit distribution,\n"
    "        2-32, default 8); --if-stale: keep FILE when it was built by this generator\n"
    "        version with these settings. One line per Monte Carlo run (run k/N, time);\n"
    "        --verbose adds each run's fit diagnostics, explained once; --quiet: none\n"
    "  info FILE                         print the axes and the generator settings\n"
    "  eval FILE --alpha-prime LIST [--g G] [--eta E] [--thickness D] [--face r|t]\n"
    "        [--edges LIST] [--cos LIST] [--radii LIST]\n"
    "        JSON: totals, annulus means of Rd over the radial edges (transport mfp), Rd at\n"
    "        --radii, exit and entry factors at the outside cosines --cos\n"
    "  mc [--g G] [--eta E] [--thickness D] [--cos-incidence C] --alpha-prime LIST\n"
    "        [--photons N] [--short-photons N] [--seed S] [--threads T]\n"
    "        JSON: the raw Monte Carlo totals (reflection and transmission) per albedo\n"
    "  invert FILE --total LIST [--g G] [--eta E]\n"
    "        the reduced albedo alpha' whose total diffuse reflectance (tables + exact single\n"
    "        scattering, normal incidence, per power entering) is each value: \"this colour\"\n"
    "  decay --albedo A [--g G]          asymptotic transport decay rate per mfp\n"
    "  version                           the generator version\n"
    "environment: SSTOOL_DEBUG=1 makes build print each albedo's tail and angular checks\n";

struct Args : shading_tools::Options {
    Args() { allow_inf = true; }
    bool flag(const std::string& k) const { return opt.count(k) > 0; }
};

Args parse(int argc, char** argv, const std::map<std::string, bool>& known) {
    Args a;
    for (int i = 2; i < argc; ++i) {
        std::string s = argv[i];
        if (s.size() > 1 && s[0] == '-' && !(s.size() > 1 && (std::isdigit(static_cast<unsigned char>(s[1])) || s[1] == '.'))) {
            auto it = known.find(s);
            if (it == known.end()) throw UsageError("unknown option " + s);
            if (it->second) {
                if (i + 1 >= argc) throw UsageError(s + " needs a value");
                a.opt[s] = argv[++i];
            } else {
                a.opt[s] = "";
            }
        } else {
            a.pos.push_back(s);
        }
    }
    return a;
}

std::vector<std::uint8_t> read_file(const std::string& path) {
    return read_file_bytes(path);  // regular files only: a directory is named as one
}

std::string jnum(double v) {
    if (std::isnan(v)) return "null";
    if (std::isinf(v)) return v > 0 ? "1e999" : "-1e999";
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.10g", v);
    return buf;
}
std::string jlist(const std::vector<double>& v) {
    std::string s = "[";
    for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + jnum(v[i]);
    return s + "]";
}

std::uint64_t count(const Args& a, const std::string& k, std::uint64_t def) {
    const double v = a.number(k, double(def));
    if (!(v >= 0 && v < 1e15) || v != std::floor(v)) throw UsageError(k + ": expected a whole number >= 0");
    return std::uint64_t(v);
}

// The settings `make brdf-data` builds with (documented in shading/DIPOLE.md).
ProfileBuildSettings build_settings(const Args& a) {
    ProfileBuildSettings s = default_profile_build_settings();
    s.g = a.list("--g", s.g);
    s.eta = a.list("--eta", s.eta);
    s.thickness = a.list("--thickness", {INFINITY});
    s.photons = count(a, "--photons", s.photons);
    s.short_photons = count(a, "--short-photons", s.short_photons);
    s.albedos = int(count(a, "--albedos", std::uint64_t(s.albedos)));
    s.angle_nodes = int(count(a, "--angle-nodes", std::uint64_t(s.angle_nodes)));
    s.seed = count(a, "--seed", s.seed);
    s.threads = int(count(a, "--threads", 0));
    return s;
}

int cmd_build(const Args& a) {
    const std::string out = a.str("-o");
    if (out.empty()) throw UsageError("build needs -o FILE");
    const ProfileBuildSettings s = build_settings(a);
    const std::string bad = s.validate();
    if (!bad.empty()) throw UsageError(bad);
    if (a.flag("--if-stale")) {
        std::ifstream probe(out, std::ios::binary);
        if (probe) {
            try {
                const std::vector<std::uint8_t> bytes = read_file(out);
                auto t = load_profile_tables(bytes.data(), bytes.size(), out);
                if (!t->stale(s)) return 0;
                std::cerr << "sstool build: warning: " << out << " was built by generator " << t->generator_version
                          << (t->generator_version == kProfileGeneratorVersion ? " with other settings" : "")
                          << " than asked for: not used; rebuilding\n";
            } catch (const std::exception& e) {
                std::cerr << "sstool build: warning: " << e.what() << ": not used; rebuilding\n";
            }
        }
    }
    const bool quiet = a.flag("--quiet"), verbose = a.flag("--verbose");
    // The library logs one line per Monte Carlo run: "g=.. d=.. (N etas): T s, ..." then, after
    // ';', fit diagnostics that are worst cases over every albedo, eta and face, noise-only
    // faces included (large values there are expected): shown with --verbose, explained once.
    const std::size_t runs = s.g.size() * s.thickness.size();
    std::size_t run = 0;
    auto t = build_profile_tables(s, [&](const std::string& line) {
        if (quiet) return;
        ++run;
        if (verbose && run == 1)
            std::cerr << "sstool build: --verbose diagnostics, per run the worst over every albedo, eta and face:\n"
                         "  tail amplitude flux/fit: where the tail beyond the reliable bins holds over 1 % of the\n"
                         "    flux, its amplitude is set by that flux; this is its ratio to the amplitude fitted to\n"
                         "    the last bins (near 1 for a smooth profile);\n"
                         "  deconvolution residual: annulus means the node values still miss after 8 passes;\n"
                         "  angle fit rms, angular/exit flux mismatch: of the high orders' exit-angle samples.\n"
                         "  Faces with almost no exits (transmission through thick slabs at low albedo) are noise\n"
                         "  and give the extreme values (1, 0.75, 1e20 and more); they carry no light a render can\n"
                         "  see. The tables' accuracy is what the tests measure against Monte Carlo\n"
                         "  (tests/test_ss_profiles.py, tests/test_ss_slabs.py; shading/DIPOLE.md).\n";
        const std::string shown = verbose ? line : line.substr(0, line.find(';'));
        std::cerr << "sstool build: run " << run << "/" << runs << ": " << shown << "\n";
    });
    const std::vector<std::uint8_t> bytes = t->serialize();
    // Check what we write before it replaces anything (the loader is the file's definition),
    // then write it whole beside the old one and rename (write_file_bytes).
    load_profile_tables(bytes.data(), bytes.size(), out + " (as built)");
    write_file_bytes(out, bytes);
    std::fprintf(stderr, "sstool build: %s: %zu bytes, %zu records, %.1f s\n", out.c_str(), bytes.size(), t->records.size(),
                 t->build_seconds);
    return 0;
}

int cmd_info(const Args& a) {
    if (a.pos.size() != 1) throw UsageError("info needs one FILE");
    const std::vector<std::uint8_t> bytes = read_file(a.pos[0]);
    auto t = load_profile_tables(bytes.data(), bytes.size(), a.pos[0]);
    std::cout << a.pos[0] << ": " << bytes.size() << " bytes\n" << t->describe();
    if (t->stale(t->settings)) std::cout << "  (built by another generator version than this tool's " << kProfileGeneratorVersion << ")\n";
    return 0;
}

int cmd_eval(const Args& a) {
    if (a.pos.size() != 1) throw UsageError("eval needs one FILE");
    const std::vector<std::uint8_t> bytes = read_file(a.pos[0]);
    auto t = load_profile_tables(bytes.data(), bytes.size(), a.pos[0]);
    const std::vector<double> aps = a.list("--alpha-prime", {});
    if (aps.empty()) throw UsageError("eval needs --alpha-prime LIST");
    const double g = a.number("--g", 0.0), eta = a.number("--eta", 1.0), d = a.number("--thickness", INFINITY);
    const std::string face = a.str("--face", "r");
    if (face != "r" && face != "t") throw UsageError("--face: r or t");
    const std::vector<double> edges = a.list("--edges", {}), cosv = a.list("--cos", {1.0}), radii = a.list("--radii", {});
    std::cout << "{\"g\": " << jnum(g) << ", \"eta\": " << jnum(eta) << ", \"thickness\": " << jnum(d) << ", \"face\": \""
              << face << "\", \"cos\": " << jlist(cosv) << ", \"edges\": " << jlist(edges) << ", \"radii\": " << jlist(radii)
              << ", \"rows\": [";
    for (std::size_t i = 0; i < aps.size(); ++i) {
        const ChannelProfile p(*t, aps[i], g, eta, d, face == "t" ? 1 : 0);
        std::vector<double> means, rd, exitf, entry;
        for (std::size_t b = 0; b + 1 < edges.size(); ++b) means.push_back(p.annulus_mean(edges[b], edges[b + 1]));
        for (double r : radii) rd.push_back(p.rd(r));
        for (double c : cosv) {
            exitf.push_back(p.exit_factor(c));
            entry.push_back(p.entry_factor(c));
        }
        std::cout << (i ? ", " : "") << "{\"alpha_prime\": " << jnum(aps[i]) << ", \"total\": " << jnum(p.total())
                  << ", \"single\": " << jnum(p.single()) << ", \"ballistic\": " << jnum(p.ballistic())
                  << ", \"annulus_means\": " << jlist(means) << ", \"rd\": " << jlist(rd) << ", \"exit_factor\": " << jlist(exitf)
                  << ", \"entry_factor\": " << jlist(entry) << ", \"radius_90\": " << jnum(p.radius_containing(0.9)) << "}";
    }
    std::cout << "]}\n";
    return 0;
}

int cmd_mc(const Args& a) {
    McSettings s;
    s.g = a.number("--g", 0.0);
    s.eta = a.list("--eta", {1.0});
    s.thickness = a.number("--thickness", INFINITY);
    const double ci = a.number("--cos-incidence", 1.0);  // outside; refracted with the first eta
    if (!(ci > 0 && ci <= 1)) throw UsageError("--cos-incidence: expected a value in (0, 1]");
    s.cos_inside = std::sqrt(1.0 - (1.0 - ci * ci) / (s.eta[0] * s.eta[0]));
    s.photons = count(a, "--photons", 100000);
    s.short_photons = count(a, "--short-photons", 0);
    s.short_orders = int(std::ceil(20.0 / (1.0 - s.g)));
    s.roulette_order = 250.0 / (1.0 - s.g);
    s.seed = count(a, "--seed", 1);
    s.threads = int(count(a, "--threads", 0));
    s.radial = false;
    const std::vector<double> aps = a.list("--alpha-prime", {});
    if (aps.empty()) throw UsageError("mc needs --alpha-prime LIST (increasing)");
    for (double ap : aps) s.albedos.push_back(ap / (1.0 - s.g + ap * s.g));
    const McResult r = run_transport_mc(s);
    auto face = [&](const McFace& f) {
        return "{\"ballistic\": " + jlist(f.ballistic) + ", \"single\": " + jlist(f.single) + ", \"single_se\": " +
               jlist(f.single_se) + ", \"multi\": " + jlist(f.multi) + ", \"multi_se\": " + jlist(f.multi_se) + "}";
    };
    std::string refl = "[", trans = "[";
    for (std::size_t e = 0; e < s.eta.size(); ++e) {
        refl += (e ? ", " : "") + face(r.top[e]);
        trans += (e ? ", " : "") + face(r.bottom[e]);
    }
    std::cout << "{\"g\": " << jnum(s.g) << ", \"eta\": " << jlist(s.eta) << ", \"thickness\": " << jnum(s.thickness)
              << ", \"cos_inside\": " << jnum(s.cos_inside) << ", \"alpha_prime\": " << jlist(aps) << ", \"albedo\": "
              << jlist(s.albedos) << ", \"reflection\": " << refl << "], \"transmission\": " << trans << "]"
              << ", \"seconds\": " << jnum(r.seconds) << ", \"threads\": " << r.threads_used << ", \"flights\": " << r.steps
              << "}\n";
    return 0;
}

// Exact single scattering per unit power entering at normal incidence: the hemispherical
// integral of Dipole::single_scatter_brdf(wo, n) cos_o over the exits, over Ft(1).
double single_albedo(double alpha_prime, double g, double eta) {
    if (!(alpha_prime > 0)) return 0.0;
    const double alpha = alpha_prime / (1.0 - g + alpha_prime * g);
    Medium m;
    m.sigma_s = Rgb(alpha);
    m.sigma_a = Rgb(1.0 - alpha);
    m.g = Rgb(g);
    m.eta = eta;
    const Dipole d(m);
    const Vec3 n(0, 0, 1);
    double sum = 0;
    const int nt = 400;
    for (int i = 0; i < nt; ++i) {  // midpoint in cos_o; the BRDF depends on wo only through cos_o at normal incidence
        const double c = (i + 0.5) / nt;
        const Vec3 wo(std::sqrt(1 - c * c), 0, c);
        sum += d.single_scatter_brdf(wo, n).r * c * 2 * kPi / nt;
    }
    return sum / fresnel_transmittance(1.0, eta);
}

int cmd_invert(const Args& a) {
    if (a.pos.size() != 1) throw UsageError("invert needs one FILE");
    const std::vector<std::uint8_t> bytes = read_file(a.pos[0]);
    auto t = load_profile_tables(bytes.data(), bytes.size(), a.pos[0]);
    const double g = a.number("--g", 0.0), eta = a.number("--eta", 1.0);
    const std::vector<double> totals = a.list("--total", {});
    if (totals.empty()) throw UsageError("invert needs --total LIST");
    std::cout << "{\"g\": " << jnum(g) << ", \"eta\": " << jnum(eta) << ", \"rows\": [";
    for (std::size_t i = 0; i < totals.size(); ++i) {
        const double ap = alpha_prime_for_total(*t, totals[i], g, eta, [&](double x) { return single_albedo(x, g, eta); });
        std::cout << (i ? ", " : "") << "{\"total\": " << jnum(totals[i]) << ", \"alpha_prime\": " << jnum(ap) << "}";
    }
    std::cout << "]}\n";
    return 0;
}

int cmd_decay(const Args& a) {
    std::printf("%.12g\n", transport_decay_rate(a.number("--albedo", 0.5), a.number("--g", 0.0)));
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2) {
        std::cerr << kUsage;
        return 2;
    }
    const std::string cmd = argv[1];
    if (cmd == "--help" || cmd == "-h" || cmd == "help") {
        std::cout << kUsage;
        return 0;
    }
    const std::map<std::string, bool> known = {
        {"-o", true},        {"--if-stale", false},     {"--g", true},          {"--eta", true},     {"--thickness", true},
        {"--photons", true}, {"--short-photons", true}, {"--albedos", true},    {"--angle-nodes", true},    {"--seed", true},    {"--threads", true},
        {"--quiet", false},  {"--verbose", false},     {"--alpha-prime", true},   {"--face", true},       {"--edges", true},   {"--cos", true},
        {"--radii", true},   {"--cos-incidence", true}, {"--albedo", true},     {"--help", false},   {"-h", false},
        {"--total", true}};
    try {
        const Args a = parse(argc, argv, known);
        if (a.flag("--help") || a.flag("-h")) {
            std::cout << kUsage;
            return 0;
        }
        if (cmd == "build") return cmd_build(a);
        if (cmd == "info") return cmd_info(a);
        if (cmd == "eval") return cmd_eval(a);
        if (cmd == "mc") return cmd_mc(a);
        if (cmd == "decay") return cmd_decay(a);
        if (cmd == "invert") return cmd_invert(a);
        if (cmd == "version") {
            std::printf("%u\n", kProfileGeneratorVersion);
            return 0;
        }
        std::cerr << "sstool: unknown command '" << cmd << "'\n" << kUsage;
        return 2;
    } catch (const UsageError& e) {
        std::cerr << "sstool " << cmd << ": " << e.what() << "\n" << kUsage;
        return 2;
    } catch (const std::invalid_argument& e) {
        std::cerr << "sstool " << cmd << ": " << e.what() << "\n";
        return 2;
    } catch (const std::exception& e) {
        std::cerr << "sstool " << cmd << ": " << e.what() << "\n";
        return 1;
    }
}
