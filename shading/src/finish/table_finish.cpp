// brdf_table finishes: a table file the renderer found, read once per key and checked whole.
#include <cstdint>
#include <string>
#include <vector>

#include "shading/core/locate.h"
#include "shading/finish/finish.h"

namespace shading {

std::shared_ptr<FinishModel> make_table_finish(const std::string& source, const FoundFile& file, bool interpolate) {
    std::shared_ptr<const BrdfTable> t = shared_table(file.key, [&]() {
        const std::int64_t size = file.size();
        if (size < 0) throw TableError(source + ": offset 0: expected a readable file, found none");
        // A folder opens too, and its size can read as 2^63 - 1: never allocate more than the
        // largest table the loader accepts.
        const std::int64_t most = std::int64_t(kTableFixedHeader + 4096 + 16) + std::int64_t(LoadOptions().max_payload_bytes);
        if (size > most)
            throw TableError(source + ": offset 0: " +
                             (size == INT64_MAX ? std::string("expected a .brdf file, found a folder: give the path of a table file in it")
                                                : "expected a .brdf file of at most " + std::to_string(most) +
                                                      " bytes, found " + std::to_string(size) + " bytes"));
        std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
        if (size > 0 && !file.read(bytes.data(), bytes.size()))
            throw TableError(source + ": offset 0: expected " + std::to_string(size) + " bytes, read fewer");
        return load_table(bytes.data(), bytes.size(), source);
    });
    return make_finish_model(t, interpolate ? Interp::Linear : Interp::Nearest);
}

std::string finish_file_unopened(const std::string& name, const std::string& found,
                                 const std::vector<std::string>& library_paths) {
    return explain_unopened(name, found, library_paths);
}

}  // namespace shading
