// Reads a text file, plain or gzip-compressed, line by line (internal to the log readers).
#pragma once

#include <zlib.h>

#include <string>

namespace mrslam::slam {

class TextLines {
 public:
  explicit TextLines(const std::string& path) : file_(gzopen(path.c_str(), "rb")) {}
  ~TextLines() { if (file_) gzclose(file_); }
  TextLines(const TextLines&) = delete;
  TextLines& operator=(const TextLines&) = delete;

  bool isOpen() const { return file_ != nullptr; }
  // False at the end of the file; `number` counts from 1.
  bool next(std::string& line, int& number) {
    line.clear();
    int c;
    bool any = false;
    while ((c = gzgetc(file_)) != -1) {
      any = true;
      if (c == '\n') break;
      line += static_cast<char>(c);
    }
    if (!any) return false;
    number = ++count_;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  }
  // After next() returned false: why reading stopped early (empty at a clean end of file), e.g.
  // a gzip stream cut off mid-way.
  std::string error() const {
    int code = Z_OK;
    const char* message = gzerror(file_, &code);
    return (code == Z_OK || code == Z_STREAM_END) ? std::string() : std::string(message ? message : "read error");
  }
  int linesRead() const { return count_; }

 private:
  gzFile file_;
  int count_ = 0;
};

}  // namespace mrslam::slam
