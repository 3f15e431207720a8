// The .brdf file format (specified in brdf_data/README.md), whole-file helpers, and the
// PNG plotter used by `brdftool plot`.
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "shading/table.h"

namespace shading {

TableGrid unfold_payload(const TableGeometry& g, std::vector<float> values) {
    TableGrid grid(g);
    if (!g.folded) {
        grid.values = std::move(values);
        return grid;
    }
    const int C = g.channels;
    uint64_t k = 0;
    for (uint32_t i = 0; i < g.n[0]; ++i)
        for (uint32_t r = i; r < g.n[0]; ++r)
            for (uint32_t q = 0; q < g.n[2]; ++q)
                for (int c = 0; c < C; ++c, ++k) grid.at(i, r, q, 0, c) = grid.at(r, i, q, 0, c) = values[k];
    return grid;
}

namespace {

constexpr char kMagic[8] = {'P', 'V', 'B', 'R', 'D', 'F', '\0', '\0'};
constexpr uint32_t kMaxDescription = 4096;
constexpr uint32_t kKnownFlags = kFlagFolded | kFlagNoDataFilled;

// Little-endian field access, independent of the host's byte order.
uint32_t rd32(const uint8_t* p) { return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24; }
uint64_t rd64(const uint8_t* p) { return uint64_t(rd32(p)) | uint64_t(rd32(p + 4)) << 32; }
double rdf64(const uint8_t* p) {
    uint64_t u = rd64(p);
    double d;
    std::memcpy(&d, &u, 8);
    return d;
}
float rdf32(const uint8_t* p) {
    uint32_t u = rd32(p);
    float f;
    std::memcpy(&f, &u, 4);
    return f;
}
void wr32(std::vector<uint8_t>& b, size_t at, uint32_t v) {
    for (int k = 0; k < 4; ++k) b[at + k] = uint8_t(v >> (8 * k));
}
void wr64(std::vector<uint8_t>& b, size_t at, uint64_t v) {
    wr32(b, at, uint32_t(v));
    wr32(b, at + 4, uint32_t(v >> 32));
}
void wrf64(std::vector<uint8_t>& b, size_t at, double d) {
    uint64_t u;
    std::memcpy(&u, &d, 8);
    wr64(b, at, u);
}

std::string hex64(uint64_t v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "0x%016llx", static_cast<unsigned long long>(v));
    return buf;
}
std::string num(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.9g", v);
    return buf;
}
std::string quoted_bytes(const uint8_t* p, size_t n) {
    std::string s = "\"";
    for (size_t k = 0; k < n; ++k) {
        if (p[k] >= 0x20 && p[k] < 0x7f && p[k] != '"' && p[k] != '\\') {
            s += char(p[k]);
        } else {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\x%02x", p[k]);
            s += buf;
        }
    }
    return s + "\"";
}
const char* axis_name(const TableGeometry& g, int a) {
    static const char* iso[] = {"theta_i", "theta_r", "phi", "unused"};
    static const char* aniso[] = {"theta_i", "phi_i", "theta_r", "phi_r"};
    return g.layout == TableLayout::Isotropic ? iso[a] : aniso[a];
}
uint64_t align16(uint64_t x) { return (x + 15) & ~uint64_t(15); }

// Node label for a payload value index (folded payloads enumerate pairs i <= r).
std::string payload_label(const TableGeometry& g, uint64_t value_index) {
    const int C = g.channels;
    uint64_t cell = value_index / C;
    uint32_t idx[4] = {0, 0, 0, 0};
    if (g.folded) {
        uint64_t pair = cell / g.n[2];
        idx[2] = uint32_t(cell % g.n[2]);
        uint32_t i = 0;
        while (pair >= g.n[0] - i) pair -= g.n[0] - i++;
        idx[0] = i;
        idx[1] = uint32_t(i + pair);
    } else {
        for (int a = g.axes() - 1; a >= 0; --a) {
            idx[a] = uint32_t(cell % g.n[a]);
            cell /= g.n[a];
        }
    }
    std::ostringstream s;
    for (int a = 0; a < g.axes(); ++a) s << (a ? " " : "") << axis_name(g, a) << "=" << num(g.axis_deg(a, idx[a]));
    s << " deg, channel " << value_index % C;
    return s.str();
}
std::string float_text(float v) {
    if (std::isnan(v)) return "nan";
    if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
    return num(v);
}

}  // namespace

uint64_t fnv1a64(const uint8_t* data, size_t size) {
    uint64_t h = 0xcbf29ce484222325ull;
    for (size_t k = 0; k < size; ++k) {
        h ^= data[k];
        h *= 0x100000001b3ull;
    }
    return h;
}

TableHeader parse_table_header(const uint8_t* d, size_t size, const std::string& name, uint64_t max_payload_bytes) {
    if (size >= 8 && std::memcmp(d, kMagic, 8) != 0)
        throw_table_error(name, 0, "magic \"PVBRDF\\x00\\x00\"", quoted_bytes(d, 8));
    if (size < kTableFixedHeader)
        throw_table_error(name, size, std::to_string(kTableFixedHeader) + "-byte header",
                          "end of data after " + std::to_string(size) + " bytes");
    TableHeader h;
    h.version = rd32(d + 8);
    if (h.version != kTableVersion)
        throw_table_error(name, 8, "version " + std::to_string(kTableVersion), std::to_string(h.version));
    h.payload_offset = rd32(d + 12);
    uint32_t layout = rd32(d + 16);
    if (layout != 1 && layout != 2)
        throw_table_error(name, 16, "layout 1 (isotropic) or 2 (anisotropic)", std::to_string(layout));
    TableGeometry& g = h.geom;
    g.layout = TableLayout(layout);
    uint32_t channels = rd32(d + 20);
    if (channels != 1 && channels != 3) throw_table_error(name, 20, "1 or 3 channels", std::to_string(channels));
    g.channels = int(channels);
    h.flags = rd32(d + 24);
    if (h.flags & ~kKnownFlags) throw_table_error(name, 24, "flags within 0x3", hex64(h.flags));
    g.folded = (h.flags & kFlagFolded) != 0;
    if (g.folded && g.layout != TableLayout::Isotropic)
        throw_table_error(name, 24, "no reciprocity-folded flag on an anisotropic table", hex64(h.flags));
    uint32_t units = rd32(d + 28);
    if (units != kUnitsPerSr) throw_table_error(name, 28, "units 1 (1/sr)", std::to_string(units));

    // Node counts, each range-checked before anything is sized from them.
    for (int a = 0; a < 4; ++a) {
        g.n[a] = rd32(d + 32 + 4 * a);
        const size_t at = 32 + 4 * size_t(a);
        if (a == 3 && g.layout == TableLayout::Isotropic) {
            if (g.n[3] != 1) throw_table_error(name, at, "1 (isotropic tables have three axes)", std::to_string(g.n[3]));
            continue;
        }
        uint32_t hi = !g.is_phi_axis(a) ? 9001 : (g.is_periodic(a) ? 36000 : 18001);
        if (g.n[a] < 2 || g.n[a] > hi)
            throw_table_error(name, at,
                              std::string(axis_name(g, a)) + " node count in [2, " + std::to_string(hi) + "]",
                              std::to_string(g.n[a]));
    }
    if (g.folded && g.n[1] != g.n[0])
        throw_table_error(name, 36, "theta_r node count = theta_i node count (" + std::to_string(g.n[0]) +
                                        ") in a reciprocity-folded table",
                          std::to_string(g.n[1]));
    for (int a = 0; a < 4; ++a) {
        const size_t at = 48 + 8 * size_t(a);
        double step = rdf64(d + at);
        double want = (a == 3 && g.layout == TableLayout::Isotropic) ? 0.0 : g.step_deg(a);
        if (!(std::fabs(step - want) <= 1e-9 * std::max(1.0, want)))
            throw_table_error(name, at,
                              std::string(axis_name(g, a)) + " step " + num(want) + " deg (from " +
                                  std::to_string(g.n[a]) + " nodes)",
                              num(step));
    }
    uint64_t values;
    try {
        values = g.values();
        if (values > (std::numeric_limits<uint64_t>::max() / 4)) throw std::overflow_error("size");
    } catch (const std::overflow_error&) {
        throw_table_error(name, 32, "node counts whose payload size fits 64 bits", g.describe());
    }
    const uint64_t want_bytes = values * 4;
    if (want_bytes > max_payload_bytes)
        throw_table_error(name, 32, "a payload of at most " + std::to_string(max_payload_bytes) + " bytes",
                          std::to_string(want_bytes) + " bytes for " + g.describe());
    h.payload_bytes = rd64(d + 80);
    if (h.payload_bytes != want_bytes)
        throw_table_error(name, 80, "payload size " + std::to_string(want_bytes) + " bytes (" + g.describe() + ")",
                          std::to_string(h.payload_bytes));
    h.checksum = rd64(d + 88);
    h.nodata_filled = rd64(d + 96);
    // The count is taken on the measured (unfolded) grid, before any reciprocity folding.
    const uint64_t measured_cells = uint64_t(g.n[0]) * g.n[1] * g.n[2] * g.n[3];
    if (h.nodata_filled > measured_cells)
        throw_table_error(name, 96, "at most " + std::to_string(measured_cells) + " filled no-data cells",
                          std::to_string(h.nodata_filled));
    uint32_t desc = rd32(d + 104);
    if (desc > kMaxDescription)
        throw_table_error(name, 104, "description of at most " + std::to_string(kMaxDescription) + " bytes",
                          std::to_string(desc));
    if (rd32(d + 108) != 0) throw_table_error(name, 108, "reserved field 0", std::to_string(rd32(d + 108)));
    const uint64_t want_offset = align16(kTableFixedHeader + desc);
    if (h.payload_offset != want_offset)
        throw_table_error(name, 12, "payload offset " + std::to_string(want_offset) + " (112-byte header + " +
                                        std::to_string(desc) + "-byte description, 16-aligned)",
                          std::to_string(h.payload_offset));
    const uint64_t total = want_offset + want_bytes;
    if (size < total)
        throw_table_error(name, size,
                          std::to_string(total) + " bytes (" + std::to_string(want_bytes) +
                              "-byte payload at offset " + std::to_string(want_offset) + ")",
                          "end of data");
    if (size > total)
        throw_table_error(name, total, "end of data", std::to_string(size - total) + " trailing bytes");
    h.description.assign(reinterpret_cast<const char*>(d + kTableFixedHeader), desc);
    for (uint64_t k = kTableFixedHeader + desc; k < want_offset; ++k)
        if (d[k] != 0) throw_table_error(name, k, "zero padding", std::to_string(d[k]));
    uint64_t sum = fnv1a64(d + want_offset, size_t(want_bytes));
    if (sum != h.checksum)
        throw_table_error(name, 88, "payload FNV-1a-64 " + hex64(h.checksum) + " (header)",
                          hex64(sum) + " (computed over bytes " + std::to_string(want_offset) + ".." +
                              std::to_string(total) + ")");
    return h;
}

ValueScan scan_table_values(const uint8_t* data, const TableHeader& h) {
    ValueScan s;
    const uint8_t* p = data + h.payload_offset;
    for (uint64_t k = 0, n = h.payload_bytes / 4; k < n; ++k) {
        float v = rdf32(p + 4 * k);
        bool bad = true;
        if (std::isnan(v))
            ++s.nan;
        else if (std::isinf(v))
            ++s.inf;
        else if (v < 0)
            ++s.negative;
        else
            bad = false;
        if (bad && s.first_bad_offset == UINT64_MAX) s.first_bad_offset = h.payload_offset + 4 * k;
    }
    return s;
}

std::unique_ptr<BrdfTable> load_table(const uint8_t* data, size_t size, const std::string& name,
                                      const LoadOptions& opt) {
    TableHeader h = parse_table_header(data, size, name, opt.max_payload_bytes);
    const TableGeometry& g = h.geom;
    const uint8_t* p = data + h.payload_offset;
    const uint64_t nv = h.payload_bytes / 4;
    // Finiteness and sign, on the caller's bytes, before the table is allocated.
    bool nodata = false;
    for (uint64_t k = 0; k < nv; ++k) {
        float v = rdf32(p + 4 * k);
        if (std::isinf(v))
            throw_table_error(name, h.payload_offset + 4 * k, "a finite value at " + payload_label(g, k), float_text(v));
        if (!(v >= 0)) {
            if (opt.nodata == NoDataPolicy::Reject)
                throw_table_error(name, h.payload_offset + 4 * k,
                                  "a value >= 0 at " + payload_label(g, k) + " (no-data policy: reject)", float_text(v));
            nodata = true;
        }
    }
    std::vector<float> values(nv);
    for (uint64_t k = 0; k < nv; ++k) values[k] = rdf32(p + 4 * k);
    TableInfo info{h.description, h.nodata_filled};
    if (!nodata) return std::make_unique<BrdfTable>(g, std::move(values), std::move(info), opt.interp);

    // No-data cells with the fill policy: fill on the full grid, fold again if folded.
    TableGrid grid = unfold_payload(g, std::move(values));
    BuildOptions bo;
    bo.nodata = NoDataPolicy::Fill;
    bo.fold = g.folded;
    bo.interp = opt.interp;
    bo.name = name;
    bo.description = h.description;
    bo.prior_nodata_filled = h.nodata_filled;
    return build_table(std::move(grid), bo);
}

std::vector<uint8_t> read_file_bytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw_table_error(path, 0, "a readable file", std::strerror(errno));
    // A directory opens too, and its "size" (seek to the end) can be 2^63 - 1 on ext4:
    // nothing but a regular file is sized from seekg/tellg.
    std::error_code ec;
    const std::filesystem::file_status st = std::filesystem::status(path, ec);
    if (ec || st.type() != std::filesystem::file_type::regular)
        throw_table_error(path, 0, "a regular file",
                          ec ? ec.message()
                             : st.type() == std::filesystem::file_type::directory ? std::string("a directory")
                                                                                    : std::string("not a regular file"));
    in.seekg(0, std::ios::end);
    std::streamoff len = in.tellg();
    in.seekg(0, std::ios::beg);
    if (len < 0) throw_table_error(path, 0, "a regular file", "no size");
    std::vector<uint8_t> bytes(static_cast<size_t>(len));
    if (len > 0 && !in.read(reinterpret_cast<char*>(bytes.data()), len))
        throw_table_error(path, uint64_t(in.gcount()), std::to_string(len) + " readable bytes", "a read error");
    return bytes;
}

void write_file_bytes(const std::string& path, const std::vector<uint8_t>& bytes) {
    // Write aside and rename, so an interrupted run never leaves a half table behind.
    const std::string tmp = path + ".tmp";
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        if (!out) throw TableError(path + ": cannot open " + tmp + " for writing: " + std::strerror(errno));
        out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
        if (!out.flush()) throw TableError(path + ": write failed: " + std::strerror(errno));
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        std::remove(tmp.c_str());
        throw TableError(path + ": cannot rename " + tmp + ": " + std::strerror(errno));
    }
}

std::unique_ptr<BrdfTable> load_table_file(const std::string& path, const LoadOptions& opt) {
    std::vector<uint8_t> bytes = read_file_bytes(path);
    return load_table(bytes.data(), bytes.size(), path, opt);
}

std::vector<uint8_t> encode_table(const BrdfTable& table) {
    const TableGeometry& g = table.geometry();
    std::string desc = table.info().description.substr(0, kMaxDescription);
    const uint64_t off = align16(kTableFixedHeader + desc.size());
    const std::vector<float>& v = table.values();
    std::vector<uint8_t> b(off + v.size() * 4, 0);
    std::memcpy(b.data(), kMagic, 8);
    wr32(b, 8, kTableVersion);
    wr32(b, 12, uint32_t(off));
    wr32(b, 16, uint32_t(g.layout));
    wr32(b, 20, uint32_t(g.channels));
    uint32_t flags = (g.folded ? kFlagFolded : 0) | (table.info().nodata_filled ? kFlagNoDataFilled : 0);
    wr32(b, 24, flags);
    wr32(b, 28, kUnitsPerSr);
    for (int a = 0; a < 4; ++a) {
        bool used = a < g.axes();
        wr32(b, 32 + 4 * a, used ? g.n[a] : 1);
        wrf64(b, 48 + 8 * a, used ? g.step_deg(a) : 0.0);
    }
    wr64(b, 80, uint64_t(v.size()) * 4);
    wr64(b, 96, table.info().nodata_filled);
    wr32(b, 104, uint32_t(desc.size()));
    std::memcpy(b.data() + kTableFixedHeader, desc.data(), desc.size());
    for (size_t k = 0; k < v.size(); ++k) {
        uint32_t u;
        std::memcpy(&u, &v[k], 4);
        wr32(b, off + 4 * k, u);
    }
    wr64(b, 88, fnv1a64(b.data() + off, v.size() * 4));
    return b;
}

void save_table_file(const BrdfTable& table, const std::string& path) { write_file_bytes(path, encode_table(table)); }

// ---------------------------------------------------------------- PNG

namespace {

uint32_t crc32_update(uint32_t crc, const uint8_t* p, size_t n) {
    static uint32_t table[256];
    static bool init = [] {
        for (uint32_t k = 0; k < 256; ++k) {
            uint32_t c = k;
            for (int j = 0; j < 8; ++j) c = (c & 1) ? 0xedb88320u ^ (c >> 1) : c >> 1;
            table[k] = c;
        }
        return true;
    }();
    (void)init;
    crc = ~crc;
    for (size_t k = 0; k < n; ++k) crc = table[(crc ^ p[k]) & 0xff] ^ (crc >> 8);
    return ~crc;
}

void put_be32(std::vector<uint8_t>& b, uint32_t v) {
    for (int k = 3; k >= 0; --k) b.push_back(uint8_t(v >> (8 * k)));
}

void png_chunk(std::vector<uint8_t>& out, const char type[4], const std::vector<uint8_t>& data) {
    put_be32(out, uint32_t(data.size()));
    size_t start = out.size();
    out.insert(out.end(), type, type + 4);
    out.insert(out.end(), data.begin(), data.end());
    put_be32(out, crc32_update(0, out.data() + start, out.size() - start));
}

}  // namespace

std::vector<uint8_t> encode_png(const Image& img) {
    if (img.width <= 0 || img.height <= 0 || img.rgb.size() != size_t(img.width) * img.height * 3)
        throw std::invalid_argument("encode_png: image size does not match its pixels");
    // Raw scanlines, each with filter byte 0 (none).
    const size_t row = size_t(img.width) * 3;
    std::vector<uint8_t> raw;
    raw.reserve((row + 1) * img.height);
    for (int y = 0; y < img.height; ++y) {
        raw.push_back(0);
        raw.insert(raw.end(), img.rgb.begin() + y * row, img.rgb.begin() + (y + 1) * row);
    }
    // zlib stream: CMF/FLG (deflate, 32K window, no dictionary, check bits), stored blocks
    // of at most 65535 bytes, Adler-32 of the raw data.
    std::vector<uint8_t> z = {0x78, 0x01};
    size_t pos = 0;
    do {
        size_t len = std::min<size_t>(65535, raw.size() - pos);
        bool last = pos + len == raw.size();
        z.push_back(last ? 1 : 0);  // BFINAL, BTYPE = 00 (stored)
        z.push_back(uint8_t(len));
        z.push_back(uint8_t(len >> 8));
        z.push_back(uint8_t(~len));
        z.push_back(uint8_t(~len >> 8));
        z.insert(z.end(), raw.begin() + pos, raw.begin() + pos + len);
        pos += len;
    } while (pos < raw.size());
    uint32_t a = 1, b = 0;
    for (uint8_t c : raw) {
        a = (a + c) % 65521;
        b = (b + a) % 65521;
    }
    put_be32(z, b << 16 | a);

    std::vector<uint8_t> out = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    std::vector<uint8_t> ihdr;
    put_be32(ihdr, uint32_t(img.width));
    put_be32(ihdr, uint32_t(img.height));
    ihdr.insert(ihdr.end(), {8, 2, 0, 0, 0});  // 8-bit, truecolour, deflate, filter 0, no interlace
    png_chunk(out, "IHDR", ihdr);
    png_chunk(out, "IDAT", z);
    png_chunk(out, "IEND", {});
    return out;
}

// ---------------------------------------------------------------- plot

namespace {

struct Colour {
    double r, g, b;
};

struct Canvas {
    Image& img;
    void blend(int x, int y, const Colour& c, double a) {
        if (x < 0 || y < 0 || x >= img.width || y >= img.height || a <= 0) return;
        uint8_t* p = &img.rgb[(size_t(y) * img.width + x) * 3];
        const double col[3] = {c.r, c.g, c.b};
        for (int k = 0; k < 3; ++k) p[k] = uint8_t(std::lround(p[k] + (col[k] - p[k]) * std::min(1.0, a)));
    }
    // Anti-aliased disc: coverage falls off over one pixel at the rim.
    void stamp(double x, double y, double radius, const Colour& c) {
        for (int py = int(std::floor(y - radius - 1)); py <= int(std::ceil(y + radius + 1)); ++py)
            for (int px = int(std::floor(x - radius - 1)); px <= int(std::ceil(x + radius + 1)); ++px) {
                double d = std::hypot(px + 0.5 - x, py + 0.5 - y);
                blend(px, py, c, std::clamp(radius + 0.5 - d, 0.0, 1.0) * 0.6);
            }
    }
    void line(double x0, double y0, double x1, double y1, double width, const Colour& c, double dash = 0) {
        double len = std::hypot(x1 - x0, y1 - y0);
        int steps = std::max(1, int(std::ceil(len * 2)));
        for (int s = 0; s <= steps; ++s) {
            double t = double(s) / steps;
            if (dash > 0 && std::fmod(t * len, 2 * dash) > dash) continue;
            stamp(x0 + (x1 - x0) * t, y0 + (y1 - y0) * t, width * 0.5, c);
        }
    }
};

// 5x7 bitmap glyphs (rows top to bottom, bit 4 = left column) for the labels we print.
const uint8_t* glyph(char ch) {
    struct G {
        char c;
        uint8_t rows[7];
    };
    static const G glyphs[] = {
        {'0', {14, 17, 19, 21, 25, 17, 14}}, {'1', {4, 12, 4, 4, 4, 4, 14}},     {'2', {14, 17, 1, 2, 4, 8, 31}},
        {'3', {31, 2, 4, 2, 1, 17, 14}},     {'4', {2, 6, 10, 18, 31, 2, 2}},    {'5', {31, 16, 30, 1, 1, 17, 14}},
        {'6', {6, 8, 16, 30, 17, 17, 14}},   {'7', {31, 1, 2, 4, 8, 8, 8}},      {'8', {14, 17, 17, 14, 17, 17, 14}},
        {'9', {14, 17, 17, 15, 1, 2, 12}},   {'.', {0, 0, 0, 0, 0, 12, 12}},     {'-', {0, 0, 0, 31, 0, 0, 0}},
        {'+', {0, 4, 4, 31, 4, 4, 0}},       {'=', {0, 0, 31, 0, 31, 0, 0}},     {'_', {0, 0, 0, 0, 0, 0, 31}},
        {':', {0, 12, 12, 0, 12, 12, 0}},    {'T', {31, 4, 4, 4, 4, 4, 4}},      {'I', {14, 4, 4, 4, 4, 4, 14}},
        {'M', {17, 27, 21, 21, 17, 17, 17}}, {'A', {14, 17, 17, 31, 17, 17, 17}}, {'X', {17, 17, 10, 4, 10, 17, 17}},
        {'E', {31, 16, 16, 30, 16, 16, 31}}, {'L', {16, 16, 16, 16, 16, 16, 31}}, {'O', {14, 17, 17, 17, 17, 17, 14}},
        {'G', {14, 17, 16, 23, 17, 17, 15}}, {'R', {30, 17, 17, 30, 20, 18, 17}}, {'B', {30, 17, 17, 30, 17, 17, 30}},
        {'D', {28, 18, 17, 17, 17, 18, 28}}, {'C', {14, 17, 16, 16, 16, 17, 14}}, {'H', {17, 17, 17, 31, 17, 17, 17}},
        {'N', {17, 17, 25, 21, 19, 17, 17}}, {'/', {1, 1, 2, 4, 8, 16, 16}},     {'S', {15, 16, 16, 14, 1, 1, 30}},
        {'P', {30, 17, 17, 30, 16, 16, 16}}, {'F', {31, 16, 16, 30, 16, 16, 16}}, {'U', {17, 17, 17, 17, 17, 17, 14}},
        {'W', {17, 17, 17, 21, 21, 21, 10}}, {'K', {17, 18, 20, 24, 20, 18, 17}}, {'V', {17, 17, 17, 17, 17, 10, 4}},
    };
    char u = char(std::toupper(static_cast<unsigned char>(ch)));
    for (const G& g : glyphs)
        if (g.c == u) return g.rows;
    return nullptr;  // drawn as a space
}

void text(Canvas& cv, int x, int y, const std::string& s, int scale, const Colour& c) {
    for (char ch : s) {
        if (const uint8_t* rows = glyph(ch))
            for (int r = 0; r < 7; ++r)
                for (int col = 0; col < 5; ++col)
                    if (rows[r] & (16 >> col))
                        for (int dy = 0; dy < scale; ++dy)
                            for (int dx = 0; dx < scale; ++dx) cv.blend(x + col * scale + dx, y + r * scale + dy, c, 1.0);
        x += 6 * scale;
    }
}

}  // namespace

Image plot_incidence_plane(const BrdfTable& table, const PlotOptions& opt) {
    if (opt.theta_i_deg.empty()) throw std::invalid_argument("plot: no theta_i given");
    for (double t : opt.theta_i_deg)
        if (!(t >= 0 && t <= 90)) throw std::invalid_argument("plot: theta_i " + num(t) + " outside [0, 90] deg");
    const int R = std::max(40, opt.panel_radius), margin = 24, title_h = 34;
    const int pw = 2 * R + 2 * margin, ph = title_h + R + 2 * margin;
    const int k = int(opt.theta_i_deg.size()), cols = std::min(k, 2), rows = (k + cols - 1) / cols;
    Image img;
    img.width = pw * cols;
    img.height = ph * rows;
    img.rgb.assign(size_t(img.width) * img.height * 3, 255);
    Canvas cv{img};
    const int C = table.geometry().channels;
    const Colour curve_col[3] = {{210, 30, 30}, {20, 150, 40}, {30, 60, 220}};
    const Colour grey{200, 200, 200}, dark{110, 110, 110}, light_col{235, 140, 0}, black{0, 0, 0};
    constexpr double kDecades = 3.0;
    constexpr int kSamples = 721;  // theta_r from -90 to 90 deg in 0.25 deg steps

    // Samples first, so a shared scale can see every panel.
    std::vector<std::vector<Rgb>> samples(k, std::vector<Rgb>(kSamples));
    std::vector<double> vmax(k, 0.0);
    for (int p = 0; p < k; ++p)
        for (int s = 0; s < kSamples; ++s) {
            double tr = -90.0 + 0.25 * s;
            // Right of the normal: the mirror side (phi = 180); left: towards the light (phi = 0).
            Rgb v = table.eval_iso(opt.theta_i_deg[p] * kPi / 180, std::fabs(tr) * kPi / 180, tr >= 0 ? kPi : 0.0);
            samples[p][s] = v;
            vmax[p] = std::max(vmax[p], C == 1 ? v.r : v.max_component());
        }
    if (opt.shared_scale) {
        double m = *std::max_element(vmax.begin(), vmax.end());
        std::fill(vmax.begin(), vmax.end(), m);
    }
    auto radius = [&](double v, double m) {
        if (!(m > 0) || !(v > 0)) return 0.0;
        if (!opt.log_scale) return v / m;
        return std::max(0.0, (std::log10(v / m) + kDecades) / kDecades);
    };
    for (int p = 0; p < k; ++p) {
        const int ox = (p % cols) * pw, oy = (p / cols) * ph;
        const double cx = ox + margin + R, cy = oy + title_h + margin + R;
        auto at = [&](double r, double theta_deg, double& x, double& y) {
            x = cx + R * r * std::sin(theta_deg * kPi / 180);
            y = cy - R * r * std::cos(theta_deg * kPi / 180);
        };
        // Guides: scale rings (quarters, or decades when logarithmic), outer ring, horizon, normal.
        std::vector<double> rings = opt.log_scale ? std::vector<double>{1 / 3.0, 2 / 3.0}
                                                  : std::vector<double>{0.25, 0.5, 0.75};
        for (double r : rings)
            for (int s = 0; s < 180; ++s) {
                double x0, y0, x1, y1;
                at(r, -90.0 + s, x0, y0);
                at(r, -89.0 + s, x1, y1);
                cv.line(x0, y0, x1, y1, 1.0, grey);
            }
        for (int s = 0; s < 180; ++s) {
            double x0, y0, x1, y1;
            at(1.0, -90.0 + s, x0, y0);
            at(1.0, -89.0 + s, x1, y1);
            cv.line(x0, y0, x1, y1, 1.2, dark);
        }
        cv.line(cx - R, cy, cx + R, cy, 1.2, dark);
        cv.line(cx, cy, cx, cy - R, 1.0, dark, 4);
        double lx, ly, mx, my;
        const double ti = opt.theta_i_deg[p];
        at(1.0, -ti, lx, ly);
        at(1.0, ti, mx, my);
        cv.line(cx, cy, mx, my, 1.0, grey, 3);  // mirror direction
        cv.line(lx, ly, cx, cy, 2.5, light_col);  // incident light
        for (int c = 0; c < C; ++c) {
            const Colour& col = C == 1 ? black : curve_col[c];
            double px = 0, py = 0;
            for (int s = 0; s < kSamples; ++s) {
                double x, y;
                at(radius(samples[p][s][c], vmax[p]), -90.0 + 0.25 * s, x, y);
                if (s) cv.line(px, py, x, y, 2.0, col);
                px = x;
                py = y;
            }
        }
        char title[96];
        std::snprintf(title, sizeof title, "THETA_I=%g MAX=%.2E%s", ti, vmax[p], opt.log_scale ? " LOG" : "");
        text(cv, ox + margin, oy + 10, title, 2, black);
    }
    return img;
}

}  // namespace shading
