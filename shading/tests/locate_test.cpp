// explain_unopened: not found (where it looked), found but refused by the I/O
// restrictions, found but unreadable for the operating system, a folder.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>

#include <sys/stat.h>
#include <unistd.h>

#include "shading/core/locate.h"

using shading::explain_unopened;

namespace {

struct TempDir {
    std::string path;
    TempDir() {
        char tmpl[] = "/tmp/locate-test-XXXXXX";
        path = ::mkdtemp(tmpl);
    }
    ~TempDir() { std::system(("rm -rf '" + path + "'").c_str()); }
};

}  // namespace

TEST(Locate, NotFoundNamesTheCurrentFolderAndEveryLibraryPath) {
    char cwd[4096];
    ASSERT_NE(::getcwd(cwd, sizeof cwd), nullptr);
    std::string m = explain_unopened("gold.brdf", "", {"/usr/share/inc/", "/opt/tables/", ""});
    EXPECT_EQ(m.rfind("not found: looked in the current folder (" + std::string(cwd) +
                      ") and the library paths /usr/share/inc, /opt/tables; ", 0), 0u) << m;
    EXPECT_NE(m.find("+L<folder>"), std::string::npos) << m;
    EXPECT_NE(explain_unopened("t.brdf", "", {}).find("(there are no library paths)"), std::string::npos);
}

TEST(Locate, AbsoluteNameIsNotSearched) {
    std::string m = explain_unopened("/nope/t.brdf", "", {"/a/"});
    EXPECT_NE(m.find("no file /nope/t.brdf"), std::string::npos) << m;
    EXPECT_EQ(m.find("library paths /a"), std::string::npos) << m;
}

TEST(Locate, FoundButRefusedByTheRestrictions) {
    TempDir d;
    const std::string f = d.path + "/t.brdf";
    std::ofstream(f) << "x";
    std::string m = explain_unopened("t.brdf", f, {d.path + "/"});
    EXPECT_EQ(m, "found at " + f + ", but the I/O restrictions (povray.conf) do not permit reading it; the message "
                 "before this one names the line that would permit it");
}

TEST(Locate, FoundButAFolderOrUnreadable) {
    TempDir d;
    EXPECT_NE(explain_unopened("t", d.path, {}).find("that is a folder"), std::string::npos);
    const std::string f = d.path + "/locked.brdf";
    std::ofstream(f) << "x";
    ::chmod(f.c_str(), 0);
    std::string m = explain_unopened("locked.brdf", f, {});
    if (::geteuid() == 0)  // root reads anything: then only the restrictions can refuse it
        EXPECT_NE(m.find("I/O restrictions"), std::string::npos) << m;
    else
        EXPECT_NE(m.find("cannot be read"), std::string::npos) << m;
    ::unlink(f.c_str());
    EXPECT_NE(explain_unopened("gone", f, {}).find("cannot be opened"), std::string::npos);
}
