#include "mrslam/atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <vector>

namespace mrslam {
namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what) { throw std::runtime_error(path + ": " + what); }

// The umask as Linux reports it (umask() itself would have to change it to read it, which
// another thread creating a file meanwhile would see).
mode_t currentUmask() {
  std::ifstream status("/proc/self/status");
  std::string key;
  while (status >> key) {
    if (key == "Umask:") {
      std::string octal;
      status >> octal;
      try {
        return static_cast<mode_t>(std::stoul(octal, nullptr, 8) & 0777);
      } catch (const std::exception&) {
        break;
      }
    }
    status.ignore(4096, '\n');
  }
  return 022;
}

// Removes the temporary file unless it was renamed onto the target.
struct TemporaryFile {
  std::string path;
  int fd = -1;
  bool renamed = false;
  ~TemporaryFile() {
    if (fd >= 0) ::close(fd);
    if (!renamed && !path.empty()) ::unlink(path.c_str());
  }
};

// Makes the rename itself survive a power loss (best effort: some file systems refuse).
void syncDirectory(const std::filesystem::path& directory) {
  const int fd = ::open(directory.empty() ? "." : directory.c_str(), O_RDONLY | O_DIRECTORY);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

// Everything `write` puts on the stream, and every way that can fail, checked.
void writeStream(const std::string& path, const std::string& file,
                 const std::function<void(std::ostream&)>& write) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  if (!out) fail(path, "cannot open for writing");
  write(out);
  out.flush();
  if (!out) fail(path, "write failed (disk full?)");
  out.close();
  if (!out) fail(path, "write failed when closing (disk full?)");
}

}  // namespace

void writeFileAtomically(const std::string& path, const std::function<void(std::ostream&)>& write) {
  namespace fs = std::filesystem;
  if (path.empty()) fail(path, "empty file name");
  // A link's target is what gets replaced (a user who links map.yaml to a map elsewhere means
  // that map). A device or pipe (/dev/stdout, /dev/full) cannot be replaced by a file: it is
  // written in place.
  std::error_code ec;
  fs::path target = fs::weakly_canonical(fs::path(path), ec);
  if (ec) target = path;
  const fs::file_status status = fs::status(target, ec);
  if (fs::exists(status) && !fs::is_regular_file(status)) return writeStream(path, target.string(), write);

  TemporaryFile temp;
  const std::string pattern = target.string() + ".XXXXXX";
  std::vector<char> name(pattern.begin(), pattern.end());
  name.push_back('\0');
  temp.fd = ::mkstemp(name.data());
  if (temp.fd < 0) fail(path, std::string("cannot create a file beside it: ") + std::strerror(errno));
  temp.path = name.data();
  if (::fchmod(temp.fd, 0666 & ~currentUmask()) != 0) fail(path, std::string("cannot set permissions: ") + std::strerror(errno));
  writeStream(path, temp.path, write);
  if (::fsync(temp.fd) != 0) fail(path, std::string("write failed when flushing to disk: ") + std::strerror(errno));
  if (::rename(temp.path.c_str(), target.c_str()) != 0)
    fail(path, std::string("cannot replace the file: ") + std::strerror(errno));
  temp.renamed = true;
  syncDirectory(target.parent_path());
}

}  // namespace mrslam
