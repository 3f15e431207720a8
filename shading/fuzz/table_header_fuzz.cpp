// libFuzzer target: the .brdf header validation alone (parse_table_header, then
// scan_table_values on what it accepted), which allocates nothing but the description.
// Fast, so it covers the header's many checks far more often than table_fuzz, which also
// builds the table (pole averaging and the ~1 deg albedo integral, ~2 ms a table).
//
// Every input is read as given and with its checksum field replaced by the FNV-1a-64 of
// the bytes from the header's payload offset to the end (fix_checksum in fuzz_util.h).
// An accepted header must describe the data exactly: a valid geometry whose payload size
// is 4 x values and ends the data. Loader errors are TableError; anything else is a crash.
#include <cstdint>

#include "fuzz_util.h"
#include "shading/tables/table.h"

using namespace shading;

namespace {
void header_checks(const uint8_t* data, size_t size) {
    TableHeader h;
    if (!table_header(data, size, &h)) return;
    h.geom.validate();  // std::invalid_argument would be a finding
    fuzz_check(h.payload_bytes == 4 * h.geom.values(), "payload size is 4 bytes a value");
    fuzz_check(uint64_t(h.payload_offset) + h.payload_bytes == size, "payload ends the data");
    fuzz_check(h.payload_offset % 16 == 0 && h.payload_offset >= kTableFixedHeader, "payload offset aligned");
    fuzz_check(h.description.size() <= 4096, "description bounded");
    ValueScan s = scan_table_values(data, h);
    fuzz_check(s.nan + s.inf + s.negative <= h.geom.values(), "scan counts bounded");
    fuzz_check((s.first_bad_offset == UINT64_MAX) == (s.nan + s.inf + s.negative == 0), "first bad offset");
    if (s.first_bad_offset != UINT64_MAX)
        fuzz_check(s.first_bad_offset >= h.payload_offset && s.first_bad_offset + 4 <= size, "bad offset in payload");
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    return run_with_fixed_checksum(data, size, header_checks, fix_checksum);
}
