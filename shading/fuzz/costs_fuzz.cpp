// libFuzzer target: the cost-file parser of `brdftool recommend --costs` (parse_costs, fit.h)
// on arbitrary bytes.
//
// A refused file is a TableError "fuzz-costs.txt: line L, offset B: expected ..." with B inside
// the data and on line L. An accepted one is ASCII text outside its comments, and holds entries whose family is printable ASCII words
// joined by one space and whose ratio is finite and in [kMinCostRatio, kMaxCostRatio]; written
// back as "FAMILY RATIO" lines (%.17g) it parses to the same entries, and cost_of(family) is the
// ratio of the family's last line. Anything else (or a failed check) is a crash.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>

#include "fuzz_util.h"
#include "shading/fit/fit.h"

using namespace shading;

namespace {

const char* const kName = "fuzz-costs.txt";

void check_error(const std::string& text, const std::string& msg) {
    const std::string head = std::string(kName) + ": line ";
    fuzz_check(msg.compare(0, head.size(), head) == 0, "error names the file and the line");
    unsigned long line = 0, offset = 0;
    fuzz_check(std::sscanf(msg.c_str() + head.size(), "%lu, offset %lu: expected ", &line, &offset) == 2,
               "error gives the line and the byte offset");
    fuzz_check(offset < text.size() || (text.empty() && offset == 0), "offset inside the data");
    unsigned long lines = 1;
    for (size_t k = 0; k < offset && k < text.size(); ++k) lines += text[k] == '\n';
    fuzz_check(lines == line, "offset on the line named");
}

void check_table(const std::string& text, const CostTable& t) {
    // Outside comments an accepted file holds printable ASCII, spaces and newlines only.
    bool comment = false;
    for (unsigned char c : text) {
        if (c == '\n') comment = false;
        else if (c == '#') comment = true;
        else if (!comment) fuzz_check((c >= 0x20 && c <= 0x7e) || c == '\t' || c == '\r' || c == '\v' || c == '\f',
                                      "accepted bytes are ASCII text");
    }
    std::string again;
    for (const auto& [key, v] : t.entries) {
        fuzz_check(!key.empty() && key.front() != ' ' && key.back() != ' ', "family trimmed");
        for (size_t k = 0; k < key.size(); ++k) {
            const unsigned char c = static_cast<unsigned char>(key[k]);
            fuzz_check((c >= 0x21 && c <= 0x7e) || (c == ' ' && key[k + 1] != ' '), "family printable, one space");
        }
        fuzz_check(std::isfinite(v) && v >= kMinCostRatio && v <= kMaxCostRatio, "ratio in range");
        char buf[40];
        std::snprintf(buf, sizeof buf, " %.17g\n", v);
        again += key + buf;
    }
    CostTable back = parse_costs(again, "round-trip");  // a TableError here is a crash (uncaught)
    fuzz_check(back.entries == t.entries, "written back, parses to the same entries");
    for (size_t k = 0; k < t.entries.size(); ++k) {
        bool last = true;
        for (size_t j = k + 1; j < t.entries.size(); ++j) last = last && t.entries[j].first != t.entries[k].first;
        if (last) fuzz_check(t.cost_of(t.entries[k].first) == t.entries[k].second, "cost_of: the last line wins");
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    CostTable t;
    try {
        t = parse_costs(text, kName);
    } catch (const TableError& e) {
        check_error(text, e.what());
        return 0;
    }
    check_table(text, t);
    return 0;
}
