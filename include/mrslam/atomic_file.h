// Files written whole or not at all. The content goes to a temporary file beside the target,
// which is flushed to disk and then replaces the target in one rename: a reader never sees half
// a map, and a write that fails (disk full, no permission, power lost midway) leaves the
// previous file as it was. A symbolic link is followed (its target is replaced); a device or a
// pipe (/dev/stdout) is written in place, as it cannot be replaced.
#pragma once

#include <functional>
#include <ostream>
#include <string>

namespace mrslam {

// Writes what `write` puts on the stream to `path`, with the permissions a new file gets under
// the process's umask. Throws std::runtime_error("<path>: <what failed>"); no temporary file is
// left behind either way.
void writeFileAtomically(const std::string& path, const std::function<void(std::ostream&)>& write);

}  // namespace mrslam
