// Messages for files a scene names and the renderer could not open (locate.h).
#include "shading/core/locate.h"

#include <cerrno>
#include <cstring>

#include <sys/stat.h>
#include <unistd.h>

namespace shading {

namespace {

std::string joined(const std::vector<std::string>& v) {
    std::string s;
    for (const std::string& x : v) {
        if (x.empty()) continue;
        std::string d = x;
        if (d.size() > 1 && d.back() == '/') d.pop_back();  // POV-Ray stores them with a trailing '/'
        s += (s.empty() ? "" : ", ") + d;
    }
    return s;
}

}  // namespace

std::string explain_unopened(const std::string& name, const std::string& found,
                             const std::vector<std::string>& library_paths) {
    if (!found.empty()) {
        struct stat st;
        if (::stat(found.c_str(), &st) != 0)
            return "found at " + found + ", but it cannot be opened: " + std::strerror(errno);
        if (S_ISDIR(st.st_mode)) return "found at " + found + ", but that is a folder, not a file";
        if (::access(found.c_str(), R_OK) != 0)
            return "found at " + found + ", but it cannot be read: " + std::strerror(errno) +
                   " (file permissions)";
        return "found at " + found +
               ", but the I/O restrictions (povray.conf) do not permit reading it; the message before "
               "this one names the line that would permit it";
    }
    if (!name.empty() && name[0] == '/')
        return "not found: no file " + name + " (an absolute name is not searched for in the library paths)";
    char cwd[4096];
    std::string where = "the current folder (" + std::string(::getcwd(cwd, sizeof cwd) ? cwd : "unknown") + ")";
    const std::string libs = joined(library_paths);
    where += libs.empty() ? " (there are no library paths)" : " and the library paths " + libs;
    return "not found: looked in " + where +
           "; put the file into one of them, or add its folder with +L<folder> (or "
           "Library_Path=<folder> in an INI file)";
}

}  // namespace shading
