// Regression tests for bugs found by the fuzzers and the bad-input review of the readers
// (issue 9). Each test names the input that used to misbehave.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "shading/tables/merl.h"
#include "shading/tables/table.h"
#include "table_files.h"

using namespace shading;

using table_files::table_error_of;

// MerlBrdf's constructor took +Inf samples for data (only parse() checked for them): the
// lookup's "no data" test is `>= 0`, which +Inf passes, so a bin shone infinitely.
TEST(Regression, MerlConstructorRejectsInfiniteSamples) {
    const MerlDims d{2, 2, 4};
    const uint64_t n = d.per_channel();
    for (double bad : {std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()}) {
        std::vector<double> raw(3 * n, 10.0);
        raw[n + 5] = bad;
        EXPECT_THROW(MerlBrdf(d, raw, "inf"), std::invalid_argument);
    }
    // No-data markers (negative, NaN) are still accepted, and read as 0.
    std::vector<double> raw(3 * n, 10.0);
    raw[3] = -1.0;
    raw[n + 3] = std::numeric_limits<double>::quiet_NaN();
    MerlBrdf m(d, raw, "nodata");
    EXPECT_EQ(m.nodata_bins(), 1u);
}

// read_file_bytes sized its buffer from seekg(end)/tellg, which for a directory on ext4 is
// 2^63 - 1: `brdftool info DIR` died with std::bad_alloc (under ASan: an allocation-size
// abort). Now anything but a regular file is a TableError naming the path, at offset 0.
TEST(Regression, ADirectoryIsNotReadAsATable) {
    const std::string dir = ::testing::TempDir();
    for (const std::string& msg :
         {table_error_of([&] { read_file_bytes(dir); }), table_error_of([&] { load_table_file(dir); }),
          table_error_of([&] { MerlBrdf::load_file(dir); })}) {
        EXPECT_EQ(msg, dir + ": offset 0: expected a regular file, found a directory (give the path of a file in it, not the folder)") << msg;
    }
    const std::string missing = dir + "no-such-file.brdf";
    const std::string msg = table_error_of([&] { read_file_bytes(missing); });
    // A missing file is named as a person says it (issue 33), not as an offset of a file that
    // was never read.
    EXPECT_EQ(msg, missing + ": no such file") << msg;
}
