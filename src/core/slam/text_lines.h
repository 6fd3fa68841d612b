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

 private:
  gzFile file_;
  int count_ = 0;
};

}  // namespace mrslam::slam
