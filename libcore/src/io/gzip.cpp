#include "pm/io/gzip.h"

#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstring>

#include "pm/base/error.h"

namespace pm {
namespace {
// zlib counts in uInt / unsigned; feed it in chunks well below that.
constexpr std::size_t kChunk = std::size_t(1) << 30;

std::string zlib_message(const z_stream& zs, int rc) {
  if (zs.msg) return zs.msg;
  switch (rc) {
    case Z_DATA_ERROR: return "invalid or incomplete deflate data";
    case Z_MEM_ERROR: return "out of memory";
    case Z_BUF_ERROR: return "no progress possible";
    case Z_STREAM_ERROR: return "inconsistent stream state";
    default: return "error code " + std::to_string(rc);
  }
}

gzFile as_gz(void* p) { return static_cast<gzFile>(p); }
}  // namespace

std::uint64_t max_inflated_size(std::uint64_t compressed) {
  // 1032:1 is deflate's limit; the slack covers headers of tiny streams.
  if (compressed > (UINT64_MAX - 4096) / 1032) return UINT64_MAX;
  return compressed * 1032 + 4096;
}

// Ends a z_stream on every way out of its scope (scripts/lsan.supp relies on
// the project never leaking zlib state itself).
struct InflateEnd {
  z_stream* zs;
  ~InflateEnd() { inflateEnd(zs); }
};
struct DeflateEnd {
  z_stream* zs;
  ~DeflateEnd() { deflateEnd(zs); }
};

std::size_t inflate_buffer(const void* in, std::size_t in_size, void* out, std::size_t out_size,
                           const std::string& what) {
  z_stream zs;
  std::memset(&zs, 0, sizeof zs);
  // 15 + 32: accept a zlib or a gzip header, detected automatically.
  if (inflateInit2(&zs, 15 + 32) != Z_OK) throw InputError(what + ": cannot initialise zlib");
  const InflateEnd end{&zs};
  const auto* src = static_cast<const unsigned char*>(in);
  auto* dst = static_cast<unsigned char*>(out);
  std::size_t in_left = in_size, out_done = 0;
  int rc = Z_OK;
  while (out_done < out_size) {
    if (zs.avail_in == 0 && in_left > 0) {
      const std::size_t n = std::min(in_left, kChunk);
      zs.next_in = const_cast<unsigned char*>(src);
      zs.avail_in = static_cast<uInt>(n);
      src += n;
      in_left -= n;
    }
    const std::size_t want = std::min(out_size - out_done, kChunk);
    zs.next_out = dst + out_done;
    zs.avail_out = static_cast<uInt>(want);
    rc = inflate(&zs, Z_NO_FLUSH);
    out_done += want - zs.avail_out;
    if (rc == Z_STREAM_END) {
      // Concatenated gzip members: continue with the next one if any input is left.
      if (zs.avail_in == 0 && in_left == 0) break;
      if (inflateReset(&zs) != Z_OK) break;
      continue;
    }
    if (rc == Z_BUF_ERROR && zs.avail_in == 0 && in_left == 0) break;  // input ran out: truncated
    if (rc != Z_OK) throw InputError(what + ": corrupt compressed data (zlib: " + zlib_message(zs, rc) + ")");
  }
  return out_done;
}

std::vector<unsigned char> deflate_buffer(const void* in, std::size_t n, bool gzip_wrapper, int level) {
  z_stream zs;
  std::memset(&zs, 0, sizeof zs);
  if (deflateInit2(&zs, level, Z_DEFLATED, gzip_wrapper ? 15 + 16 : 15, 8, Z_DEFAULT_STRATEGY) != Z_OK)
    throw Error("deflate_buffer: cannot initialise zlib");
  const DeflateEnd end{&zs};
  std::vector<unsigned char> out;
  const auto* src = static_cast<const unsigned char*>(in);
  std::size_t in_left = n;
  unsigned char buf[1 << 16];
  int rc = Z_OK;
  do {
    if (zs.avail_in == 0 && in_left > 0) {
      const std::size_t c = std::min(in_left, kChunk);
      zs.next_in = const_cast<unsigned char*>(src);
      zs.avail_in = static_cast<uInt>(c);
      src += c;
      in_left -= c;
    }
    zs.next_out = buf;
    zs.avail_out = sizeof buf;
    rc = deflate(&zs, in_left == 0 ? Z_FINISH : Z_NO_FLUSH);
    if (rc == Z_STREAM_ERROR) throw Error("deflate_buffer: zlib stream error");
    out.insert(out.end(), buf, buf + (sizeof buf - zs.avail_out));
  } while (rc != Z_STREAM_END);
  return out;
}

GzipReader::GzipReader(const std::string& path, const std::string& what) : what_(what) {
  errno = 0;
  gzFile f = gzopen(path.c_str(), "rb");
  if (!f) throw IoError(what + ": cannot open: " + (errno ? std::strerror(errno) : "zlib error"));
  gzbuffer(f, 1 << 17);
  file_ = f;
}

GzipReader::~GzipReader() {
  if (file_) gzclose(as_gz(file_));
}

bool GzipReader::compressed() const { return gzdirect(as_gz(file_)) == 0; }

std::size_t GzipReader::read(void* buf, std::size_t n) {
  auto* dst = static_cast<unsigned char*>(buf);
  std::size_t done = 0;
  while (done < n) {
    const unsigned want = static_cast<unsigned>(std::min(n - done, kChunk));
    const int got = gzread(as_gz(file_), dst + done, want);
    if (got < 0) {
      int code = 0;
      const char* m = gzerror(as_gz(file_), &code);
      if (code == Z_BUF_ERROR) break;  // unexpected end of a gzip stream: truncated
      throw InputError(what_ + ": corrupt compressed data (zlib: " + (m ? m : "?") + ")");
    }
    if (got == 0) break;
    done += static_cast<std::size_t>(got);
  }
  return done;
}

GzipWriter::GzipWriter(const std::string& path, bool compress, const std::string& what, int level)
    : what_(what) {
  const std::string mode = compress ? "wb" + std::to_string(std::clamp(level, 0, 9)) : std::string("wbT");
  errno = 0;
  gzFile f = gzopen(path.c_str(), mode.c_str());
  if (!f) throw IoError(what + ": cannot create: " + (errno ? std::strerror(errno) : "zlib error"));
  gzbuffer(f, 1 << 17);
  file_ = f;
}

GzipWriter::~GzipWriter() {
  if (file_) gzclose(as_gz(file_));
}

void GzipWriter::write(const void* buf, std::size_t n) {
  const auto* src = static_cast<const unsigned char*>(buf);
  while (n > 0) {
    const unsigned c = static_cast<unsigned>(std::min(n, kChunk));
    errno = 0;
    const int put = gzwrite(as_gz(file_), src, c);
    if (put <= 0) {
      int code = 0;
      const char* m = gzerror(as_gz(file_), &code);
      throw IoError(what_ + ": write failed: " +
                    (code == Z_ERRNO && errno ? std::strerror(errno) : (m ? m : "zlib error")));
    }
    src += put;
    n -= static_cast<std::size_t>(put);
  }
}

void GzipWriter::close() {
  if (!file_) return;
  errno = 0;
  const int rc = gzclose(as_gz(file_));
  file_ = nullptr;
  if (rc != Z_OK)
    throw IoError(what_ + ": closing failed: " + (errno ? std::strerror(errno) : "zlib error"));
}

}  // namespace pm
