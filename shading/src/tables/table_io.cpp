// The .brdf file format (specified in brdf_data/README.md) and whole-file helpers.
#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "shading/tables/table.h"

#include <fcntl.h>
#include <unistd.h>

#include "shading/core/bytes.h"
#include "shading/core/format.h"

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

using bytes::rd_f32;
using bytes::rd_u32;
using bytes::rd_u64;
using bytes::wr_f32;
using bytes::rd_f64;
using bytes::wr_f64;
using bytes::wr_u32;
using bytes::wr_u64;

using detail::hex64;
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
    for (int a = 0; a < g.axes(); ++a) s << (a ? " " : "") << g.axis_name(a) << "=" << detail::fmt(g.axis_deg(a, idx[a]), 9);
    s << " deg, channel " << value_index % C;
    return s.str();
}

// What a value above kMaxTableValue should have been, for the loader and the writer alike.
std::string within_bound(const TableGeometry& g, uint64_t value_index, const char* also) {
    char bound[32];
    std::snprintf(bound, sizeof bound, "%g", kMaxTableValue);
    return std::string("a value <= ") + bound + " (1/sr) at " + payload_label(g, value_index) +
           " (larger is a unit or scale error" + also + ": brdf_data/README.md)";
}

}  // namespace

TableHeader parse_table_header(const uint8_t* d, size_t size, const std::string& name, uint64_t max_payload_bytes) {
    if (size >= 8 && std::memcmp(d, kMagic, 8) != 0)
        throw_table_error(name, 0, "magic \"PVBRDF\\x00\\x00\"", quoted_bytes(d, 8));
    if (size < kTableFixedHeader)
        throw_table_error(name, size, std::to_string(kTableFixedHeader) + "-byte header",
                          "end of data after " + std::to_string(size) + " bytes");
    TableHeader h;
    h.version = rd_u32(d + 8);
    if (h.version != kTableVersion)
        throw_table_error(name, 8, "version " + std::to_string(kTableVersion), std::to_string(h.version));
    h.payload_offset = rd_u32(d + 12);
    uint32_t layout = rd_u32(d + 16);
    if (layout != 1 && layout != 2 && layout != 3)
        throw_table_error(name, 16, "layout 1 (isotropic), 2 (anisotropic) or 3 (half/difference)",
                          std::to_string(layout));
    TableGeometry& g = h.geom;
    g.layout = TableLayout(layout);
    uint32_t channels = rd_u32(d + 20);
    if (channels != 1 && channels != 3) throw_table_error(name, 20, "1 or 3 channels", std::to_string(channels));
    g.channels = int(channels);
    h.flags = rd_u32(d + 24);
    if (h.flags & ~kKnownFlags) throw_table_error(name, 24, "flags within 0x3", hex64(h.flags));
    g.folded = (h.flags & kFlagFolded) != 0;
    if (g.folded && g.layout != TableLayout::Isotropic)
        throw_table_error(name, 24,
                          std::string("no reciprocity-folded flag on ") +
                              (g.layout == TableLayout::Anisotropic ? "an anisotropic table"
                                                                    : "a half/difference table (reciprocal by construction)"),
                          hex64(h.flags));
    uint32_t units = rd_u32(d + 28);
    if (units != kUnitsPerSr) throw_table_error(name, 28, "units 1 (1/sr)", std::to_string(units));

    // Node counts, each range-checked before anything is sized from them.
    for (int a = 0; a < 4; ++a) {
        g.n[a] = rd_u32(d + 32 + 4 * a);
        const size_t at = 32 + 4 * size_t(a);
        if (a == 3 && g.layout != TableLayout::Anisotropic) {
            if (g.n[3] != 1)
                throw_table_error(name, at,
                                  std::string("1 (") +
                                      (g.layout == TableLayout::Isotropic ? "isotropic" : "half/difference") +
                                      " tables have three axes)",
                                  std::to_string(g.n[3]));
            continue;
        }
        const uint32_t hi = g.max_nodes(a);
        if (g.n[a] < 2 || g.n[a] > hi)
            throw_table_error(name, at,
                              std::string(g.axis_name(a)) + " node count in [2, " + std::to_string(hi) + "]",
                              std::to_string(g.n[a]));
    }
    if (g.folded && g.n[1] != g.n[0])
        throw_table_error(name, 36, "theta_r node count = theta_i node count (" + std::to_string(g.n[0]) +
                                        ") in a reciprocity-folded table",
                          std::to_string(g.n[1]));
    for (int a = 0; a < 4; ++a) {
        const size_t at = 48 + 8 * size_t(a);
        double step = rd_f64(d + at);
        double want = (a == 3 && g.layout != TableLayout::Anisotropic) ? 0.0 : g.step_deg(a);
        if (!(std::fabs(step - want) <= 1e-9 * std::max(1.0, want)))
            throw_table_error(name, at,
                              std::string(g.axis_name(a)) + " step " + detail::fmt(want, 9) + " deg (from " +
                                  std::to_string(g.n[a]) + " nodes)",
                              detail::fmt(step, 9));
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
    h.payload_bytes = rd_u64(d + 80);
    if (h.payload_bytes != want_bytes)
        throw_table_error(name, 80, "payload size " + std::to_string(want_bytes) + " bytes (" + g.describe() + ")",
                          std::to_string(h.payload_bytes));
    h.checksum = rd_u64(d + 88);
    h.nodata_filled = rd_u64(d + 96);
    // The count is taken on the measured (unfolded) grid, before any reciprocity folding.
    const uint64_t measured_cells = uint64_t(g.n[0]) * g.n[1] * g.n[2] * g.n[3];
    if (h.nodata_filled > measured_cells)
        throw_table_error(name, 96, "at most " + std::to_string(measured_cells) + " filled no-data cells",
                          std::to_string(h.nodata_filled));
    uint32_t desc = rd_u32(d + 104);
    if (desc > kMaxDescription)
        throw_table_error(name, 104, "description of at most " + std::to_string(kMaxDescription) + " bytes",
                          std::to_string(desc));
    if (rd_u32(d + 108) != 0) throw_table_error(name, 108, "reserved field 0", std::to_string(rd_u32(d + 108)));
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
        float v = rd_f32(p + 4 * k);
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
        float v = rd_f32(p + 4 * k);
        if (std::isinf(v))
            throw_table_error(name, h.payload_offset + 4 * k, "a finite value at " + payload_label(g, k), detail::fmt_float(v));
        if (v > kMaxTableValue)
            throw_table_error(name, h.payload_offset + 4 * k, within_bound(g, k, ", or damage"), detail::fmt_float(v));
        if (!(v >= 0)) {
            if (opt.nodata == NoDataPolicy::Reject)
                throw_table_error(name, h.payload_offset + 4 * k,
                                  "a value >= 0 at " + payload_label(g, k) + " (no-data policy: reject)", detail::fmt_float(v));
            nodata = true;
        }
    }
    std::vector<float> values(nv);
    for (uint64_t k = 0; k < nv; ++k) values[k] = rd_f32(p + 4 * k);
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

void require_regular_file(const std::string& path, const std::string& name) {
    // A directory opens too, and its "size" (seek to the end) can be 2^63 - 1 on ext4:
    // nothing but a regular file is sized from seekg/tellg.
    std::error_code ec;
    const std::filesystem::file_status st = std::filesystem::status(path, ec);
    if (ec || st.type() != std::filesystem::file_type::regular)
        throw_table_error(name, 0, "a regular file",
                          ec ? ec.message()
                             : st.type() == std::filesystem::file_type::directory
                                   ? std::string("a directory (give the path of a file in it, not the folder)")
                                   : std::string("not a regular file (a device, pipe or socket)"));
}

std::vector<uint8_t> read_file_bytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        // Nothing was read, so no offset: say what is wrong with the name, as a person would.
        const int e = errno;
        if (e == ENOENT) throw TableError(path + ": no such file");
        if (e == EACCES) throw TableError(path + ": not readable (permission denied)");
        throw TableError(path + ": cannot be opened (" + std::strerror(e) + ")");
    }
    require_regular_file(path, path);
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
    // Written whole under a name of its own in the same folder (same file system: the rename is
    // atomic), flushed to disk, then renamed over `path`: a reader sees the old file or the new
    // one, never a part, and two writers of the same path do not share a temporary file.
    static std::atomic<unsigned> counter{0};
    std::string tmp;
    int fd = -1;
    for (int attempt = 0; fd < 0 && attempt < 100; ++attempt) {
        tmp = path + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter++);
        fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);  // 0666 & ~umask, like the file it replaces
        if (fd < 0 && errno != EEXIST) break;
    }
    if (fd < 0) throw TableError(path + ": cannot create a temporary file beside it (" + tmp + "): " + std::strerror(errno));
    auto fail = [&](const std::string& what) {
        const int err = errno;
        ::close(fd);
        std::remove(tmp.c_str());
        throw TableError(path + ": " + what + " " + tmp + ": " + std::strerror(err));
    };
    for (size_t done = 0; done < bytes.size();) {
        const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) fail("cannot write");
        done += size_t(n);
    }
    if (::fsync(fd) != 0) fail("cannot flush");
    if (::close(fd) != 0) {
        const int err = errno;
        std::remove(tmp.c_str());
        throw TableError(path + ": cannot close " + tmp + ": " + std::strerror(err));
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        const int err = errno;
        std::remove(tmp.c_str());
        throw TableError(path + ": cannot rename " + tmp + " into place: " + std::strerror(err));
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
    // Never write what load_table refuses (a converted measurement, a tabulated model).
    for (size_t k = 0; k < v.size(); ++k)
        if (v[k] > kMaxTableValue)
            throw_table_error("table", off + 4 * k, within_bound(g, k, ""), detail::fmt_float(v[k]));
    std::vector<uint8_t> b(off + v.size() * 4, 0);
    std::memcpy(b.data(), kMagic, 8);
    wr_u32(b, 8, kTableVersion);
    wr_u32(b, 12, uint32_t(off));
    wr_u32(b, 16, uint32_t(g.layout));
    wr_u32(b, 20, uint32_t(g.channels));
    uint32_t flags = (g.folded ? kFlagFolded : 0) | (table.info().nodata_filled ? kFlagNoDataFilled : 0);
    wr_u32(b, 24, flags);
    wr_u32(b, 28, kUnitsPerSr);
    for (int a = 0; a < 4; ++a) {
        bool used = a < g.axes();
        wr_u32(b, 32 + 4 * a, used ? g.n[a] : 1);
        wr_f64(b, 48 + 8 * a, used ? g.step_deg(a) : 0.0);
    }
    wr_u64(b, 80, uint64_t(v.size()) * 4);
    wr_u64(b, 96, table.info().nodata_filled);
    wr_u32(b, 104, uint32_t(desc.size()));
    std::memcpy(b.data() + kTableFixedHeader, desc.data(), desc.size());
    for (size_t k = 0; k < v.size(); ++k) wr_f32(b, off + 4 * k, v[k]);
    wr_u64(b, 88, fnv1a64(b.data() + off, v.size() * 4));
    return b;
}

void save_table_file(const BrdfTable& table, const std::string& path) { write_file_bytes(path, encode_table(table)); }

}  // namespace shading
