#include "pm/base/atomic_file.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <set>
#include <vector>

#include "pm/base/error.h"

namespace fs = std::filesystem;

namespace pm {
namespace {
// Pending temporary files, for the signal handler. A fixed-size table of
// C strings so the handler can unlink without allocating.
constexpr int kMaxPending = 64;
char g_pending[kMaxPending][4096];
std::atomic<bool> g_used[kMaxPending];
std::mutex g_mutex;

int register_pending(const std::string& p) {
  std::lock_guard<std::mutex> lock(g_mutex);
  for (int i = 0; i < kMaxPending; ++i) {
    if (!g_used[i].load()) {
      std::snprintf(g_pending[i], sizeof g_pending[i], "%s", p.c_str());
      g_used[i].store(true);
      return i;
    }
  }
  return -1;
}
void unregister_pending(int slot) {
  if (slot >= 0) g_used[slot].store(false);
}
std::atomic<unsigned> g_counter{0};

struct Deferred {
  std::string temp, target;
  int slot;
};
bool g_defer = false;
std::vector<Deferred> g_deferred;
std::atomic<bool> g_committing{false};
std::atomic<int> g_commit_signal{0};

void remove_with_detached_data(const std::string& temp) {
  std::error_code ec;
  fs::remove(temp, ec);
  // detached NRRD data files written beside a .nhdr
  const std::string ext = file_extension(temp);
  for (const char* extra : {".raw", ".raw.gz"}) fs::remove(temp.substr(0, temp.size() - ext.size()) + extra, ec);
}
}  // namespace

std::string file_extension(const std::string& path) {
  const std::string name = fs::path(path).filename().string();
  std::string lower = name;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
  for (const char* two : {".nii.gz", ".inr.gz", ".nrrd.gz"}) {
    const std::string t(two);
    if (lower.size() > t.size() && lower.compare(lower.size() - t.size(), t.size(), t) == 0) return t;
  }
  const auto dot = lower.rfind('.');
  if (dot == std::string::npos || dot == 0) return "";
  return lower.substr(dot);
}

void require_readable(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw IoError(quote(path) + ": no such file");
  if (fs::is_directory(path, ec)) throw IoError(quote(path) + ": is a directory; expected a file");
  if (::access(path.c_str(), R_OK) != 0) throw IoError(quote(path) + ": not readable: " + std::strerror(errno));
}

AtomicFile::AtomicFile(const std::string& target) : target_(target) {
  fs::path t(target);
  fs::path dir = t.parent_path();
  if (dir.empty()) dir = ".";
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw IoError(quote(target) + ": output folder " + quote(dir.string()) + " does not exist");
  if (::access(dir.c_str(), W_OK) != 0)
    throw IoError(quote(target) + ": output folder " + quote(dir.string()) + " is not writable");
  if (fs::is_directory(t, ec)) throw IoError(quote(target) + ": is a directory; expected a file name");
  const std::string ext = file_extension(target);
  const std::string stem = t.filename().string().substr(0, t.filename().string().size() - ext.size());
  temp_ = (dir / ("." + stem + ".tmp" + std::to_string(::getpid()) + "_" + std::to_string(g_counter++) + ext))
              .string();
  slot_ = register_pending(temp_);
}

AtomicFile::~AtomicFile() {
  if (!committed_) remove_with_detached_data(temp_);
  unregister_pending(slot_);
}

void AtomicFile::commit() {
  std::error_code ec;
  if (!fs::exists(temp_, ec)) throw IoError(quote(target_) + ": nothing was written");
  if (g_defer) {
    std::lock_guard<std::mutex> lock(g_mutex);
    g_deferred.push_back({temp_, target_, slot_});
    slot_ = -1;  // the deferred list owns the registration now
    committed_ = true;
    return;
  }
  fs::rename(temp_, target_, ec);
  if (ec) throw IoError(quote(target_) + ": cannot rename temporary file into place: " + ec.message());
  committed_ = true;
}

void write_atomically(const std::string& target, const std::function<void(const std::string&)>& writer) {
  AtomicFile f(target);
  writer(f.temp_path());
  f.commit();
}

void defer_commits(bool on) { g_defer = on; }

int commit_deferred() {
  std::vector<Deferred> list;
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    list.swap(g_deferred);
  }
  g_committing.store(true);
  std::size_t i = 0;
  try {
    for (; i < list.size(); ++i) {
      std::error_code ec;
      fs::rename(list[i].temp, list[i].target, ec);
      if (ec)
        throw IoError(quote(list[i].target) + ": cannot rename temporary file into place: " + ec.message());
      unregister_pending(list[i].slot);
    }
  } catch (...) {
    for (; i < list.size(); ++i) {
      remove_with_detached_data(list[i].temp);
      unregister_pending(list[i].slot);
    }
    g_committing.store(false);
    throw;
  }
  g_committing.store(false);
  return g_commit_signal.exchange(0);
}

void discard_deferred() noexcept {
  std::lock_guard<std::mutex> lock(g_mutex);
  for (const Deferred& d : g_deferred) {
    remove_with_detached_data(d.temp);
    unregister_pending(d.slot);
  }
  g_deferred.clear();
}

bool hold_signal_during_commit(int sig) noexcept {
  if (!g_committing.load()) return false;
  g_commit_signal.store(sig);
  return true;
}

void remove_pending_temp_files() noexcept {
  for (int i = 0; i < kMaxPending; ++i)
    if (g_used[i].load()) ::unlink(g_pending[i]);
}

}  // namespace pm
