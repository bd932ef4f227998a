#pragma once
// Internal zlib helpers for the volume readers and writers: whole-buffer
// inflate/deflate (MetaImage zraw) and streamed, optionally gzip-compressed
// files (INRimage .inr / .inr.gz).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace pm {

/// Upper bound on the bytes a deflate stream (zlib or gzip wrapped) of
/// `compressed` bytes can expand to (deflate's ratio is at most 1032:1).
/// Readers compare it with the size a header claims before allocating.
std::uint64_t max_inflated_size(std::uint64_t compressed);

/// Inflate a zlib or gzip stream (detected from its first bytes) into
/// out[0, out_size). Returns the number of bytes produced, which is less than
/// out_size when the stream ends early; stops at out_size.
/// \throw InputError "<what>: corrupt compressed data (zlib: ...)" on a bad stream.
std::size_t inflate_buffer(const void* in, std::size_t in_size, void* out, std::size_t out_size,
                           const std::string& what);

/// Deflate `n` bytes into a zlib stream (gzip_wrapper = false; MetaImage zraw)
/// or a gzip stream. level: 0..9, -1 for zlib's default.
std::vector<unsigned char> deflate_buffer(const void* in, std::size_t n, bool gzip_wrapper = false,
                                          int level = -1);

/// Reads a file that may be gzip-compressed; plain files are read as they are.
class GzipReader {
 public:
  /// \throw IoError "<what>: cannot open: ..." when the file cannot be opened.
  GzipReader(const std::string& path, const std::string& what);
  ~GzipReader();
  GzipReader(const GzipReader&) = delete;
  GzipReader& operator=(const GzipReader&) = delete;

  /// Read up to n bytes; returns fewer only at the end of the (decompressed)
  /// stream. \throw InputError on corrupt compressed data.
  std::size_t read(void* buf, std::size_t n);
  /// True when the file is gzip-compressed.
  bool compressed() const;

 private:
  void* file_ = nullptr;  // gzFile
  std::string what_;
};

/// Writes a file, gzip-compressed or plain.
class GzipWriter {
 public:
  /// \throw IoError when the file cannot be created.
  GzipWriter(const std::string& path, bool compress, const std::string& what, int level = 6);
  ~GzipWriter();
  GzipWriter(const GzipWriter&) = delete;
  GzipWriter& operator=(const GzipWriter&) = delete;

  /// \throw IoError on a write failure (disk full, ...).
  void write(const void* buf, std::size_t n);
  /// Flush and close. \throw IoError on failure. The destructor closes silently.
  void close();

 private:
  void* file_ = nullptr;  // gzFile
  std::string what_;
};

}  // namespace pm
