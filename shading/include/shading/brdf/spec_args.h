// What a model's own file uses to read its spec (SpecArgs, SpecKey), to write it back
// (SpecWriter), and, for a model whose keys are all numbers and colours, to make its help,
// parser and writer from one table (SpecParam). make_brdf() and the registry: model_spec.h.
#pragma once

#include <cstddef>
#include <initializer_list>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "shading/brdf/model_spec.h"
#include "shading/core/format.h"
#include "shading/core/vec.h"

namespace shading {

// Throws std::invalid_argument("make_brdf: " + msg).
[[noreturn]] void spec_error(const std::string& msg);

// One key of a model: its name, what it is, its range. The default is read from a
// default-constructed model (the class holds every default; the help prints it from there).
struct SpecKey {
    const char* name;
    const char* type;  // "<x>", "<rgb>" or the choices "a|b"
    const char* what;
    double lo = 1, hi = 0;  // lo > hi: no range (words, repeatable keys)
    const char* note = "";  // after the range
};
// One help line: "name=type  what, default D, range [lo,hi]note" (def empty: no default).
std::string help_line(const SpecKey& k, const std::string& def);

// The "key=value" list of one spec, with typed, range-checked accessors. Every accessor marks
// its key used; finish() rejects the keys nobody asked for, naming them.
class SpecArgs {
public:
    SpecArgs(std::string model, std::vector<std::pair<std::string, std::string>> kv)
        : model_(std::move(model)), kv_(std::move(kv)) {}

    bool has(const std::string& key) const;
    // All values of a key that may repeat (e.g. lafortune's lobe=).
    std::vector<std::string> all(const std::string& key);
    // The single value of a key, or nullptr when absent; a repeated key is an error.
    const std::string* one(const std::string& key);
    // "MODEL: key 'KEY': ", the start of every message about a key.
    std::string where(const std::string& key) const;

    double number(const std::string& key, double def, double lo, double hi, bool required = false);
    double number(const SpecKey& k, double def, bool required = false) { return number(k.name, def, k.lo, k.hi, required); }
    // Scalar "0.5" (grey) or triple "0.2,0.4,0.6"; each component in [lo, hi].
    Rgb rgb(const std::string& key, const Rgb& def, double lo, double hi, bool required = false);
    Rgb rgb(const SpecKey& k, const Rgb& def, bool required = false) { return rgb(k.name, def, k.lo, k.hi, required); }
    std::string word(const std::string& key, const std::string& def, const std::vector<std::string>& allowed);
    // A comma-separated list of numbers (no range check).
    std::vector<double> numbers(const std::string& key, const std::string& v) const;

    // Energy bound of the normalised models: a + b <= 1 in every channel (tolerance 1e-12).
    void check_sum(const char* ka, const Rgb& a, const char* kb, const Rgb& b) const;
    // Keys that belong to one choice of a word key; given with another choice they are errors.
    void forbid(const std::vector<std::string>& keys, const std::string& why) const;
    void finish() const;

private:
    double parse_number(const std::string& key, const std::string& text) const;
    void check_range(const std::string& key, double x, double lo, double hi) const;

    std::string model_;
    std::vector<std::pair<std::string, std::string>> kv_;
    std::set<std::string> used_;
};

// Writes "<model> key=value ..." in the spec grammar. Numbers get `digits` significant digits
// (printf's %g), or with digits = 0 the fewest from 6 up that parse back to the same double,
// so that make_brdf(b.spec()) rebuilds b to the bit. A colour with three equal channels is
// written as one number.
class SpecWriter {
public:
    explicit SpecWriter(int digits = 0) : digits_(digits) {}
    SpecWriter& model(const char* name);
    SpecWriter& word(const char* key, const char* value);
    SpecWriter& number(const char* key, double v);
    SpecWriter& rgb(const char* key, const Rgb& v);
    // "key=a,b,c,...": a list of numbers (lafortune's lobe=).
    SpecWriter& list(const char* key, std::initializer_list<double> values);
    const std::string& str() const { return s_; }

private:
    std::string text(double v) const;
    SpecWriter& put(const char* key, const std::string& value);
    int digits_;
    std::string s_;
};

// ---------------------------------------------------------------- plain models

// One plain key of a model, a number or a colour, and the member it sets. A model whose keys
// are all plain lists them in one table, in help order; its help, its parser and its spec
// writer are all made from that table, so the three cannot drift apart.
template <class M>
struct SpecParam {
    constexpr SpecParam(const SpecKey& k, Rgb M::*c) : key(k), colour(c) {}
    constexpr SpecParam(const SpecKey& k, double M::*x) : key(k), number(x) {}
    SpecKey key;
    Rgb M::*colour = nullptr;
    double M::*number = nullptr;
};

// The registry entry of a plain model (defaults read from a default-constructed M); `check`,
// if given, runs once every key is read (e.g. an energy bound over two keys).
template <class M, std::size_t N>
ModelEntry plain_model_entry(const char* name, const char* summary, const SpecParam<M> (&params)[N],
                             std::vector<ModelExample> examples, std::vector<std::pair<std::string, double>> costs,
                             void (*check)(const SpecArgs&, const M&) = nullptr) {
    ModelEntry m;
    m.name = name;
    m.summary = summary;
    m.keys = [&params] {
        const M d;
        std::string s;
        for (const SpecParam<M>& p : params) s += help_line(p.key, p.colour ? detail::fmt(d.*p.colour) : detail::fmt(d.*p.number));
        return s;
    };
    m.make = [&params, check](SpecArgs& a) -> BrdfPtr {
        auto b = std::make_shared<M>();
        for (const SpecParam<M>& p : params) {
            if (p.colour)
                (*b).*p.colour = a.rgb(p.key, (*b).*p.colour);
            else
                (*b).*p.number = a.number(p.key, (*b).*p.number);
        }
        if (check) check(a, *b);
        return b;
    };
    m.examples = std::move(examples);
    m.costs = std::move(costs);
    return m;
}

// A plain model's spec: its name, then every key of its table.
template <class M, std::size_t N>
void write_params(SpecWriter& w, const char* name, const SpecParam<M> (&params)[N], const M& m) {
    w.model(name);
    for (const SpecParam<M>& p : params) {
        if (p.colour)
            w.rgb(p.key.name, m.*p.colour);
        else
            w.number(p.key.name, m.*p.number);
    }
}

}  // namespace shading
