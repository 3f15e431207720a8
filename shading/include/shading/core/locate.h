// Why a file a scene names could not be opened, in words, for the renderer's error
// message (brdf_table today). POV-Ray looks for a relative name in the current folder,
// then in each library path (+L, Library_Path), and opens what it found only if the I/O
// restrictions (povray.conf) permit it; an absolute name is looked at only where it
// points. The adapter passes what POV-Ray found (if anything) and where it searched; this
// says which of "not found" (and where it looked) or "found but not permitted" happened.
#pragma once

#include <string>
#include <vector>

namespace shading {

// `name`: as the scene wrote it. `found`: the path POV-Ray found for it, "" when none.
// `library_paths`: the folders searched after the current folder, in order.
// The text continues a message that starts with the file's name, e.g.
//   "not found: looked in the current folder (/home/u/proj) and the library paths
//    /usr/share/povray-3.7/include, /opt/tables; put the file into one of them, or add its
//    folder with +L<folder> (or Library_Path=<folder> in an INI file)"
//   "found at /srv/t.brdf, but the I/O restrictions (povray.conf) do not permit reading it;
//    the message before this one names the line that would permit it"
//   "found at /srv/t.brdf, but it cannot be read: permission denied"
std::string explain_unopened(const std::string& name, const std::string& found,
                             const std::vector<std::string>& library_paths);

}  // namespace shading
