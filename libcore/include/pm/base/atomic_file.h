#pragma once
// Atomic output: write to a temporary file in the target's folder, rename on commit.
#include <functional>
#include <string>

namespace pm {

/// A temporary path next to `target`; the file is renamed onto `target` by
/// commit() and deleted by the destructor if commit() was never called.
/// Temporary paths are registered so SIGINT/SIGTERM handlers can remove them.
class AtomicFile {
 public:
  /// \throw IoError when the target's folder does not exist or is not writable.
  explicit AtomicFile(const std::string& target);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  /// Path to write to. It keeps the target's extension(s) so libraries that
  /// choose a format by extension (Teem, OpenVDB) see the right one.
  const std::string& temp_path() const { return temp_; }
  const std::string& target() const { return target_; }
  /// Rename into place. \throw IoError on failure.
  void commit();

 private:
  std::string target_, temp_;
  bool committed_ = false;
  int slot_ = -1;
};

/// Convenience: write via `writer(temp_path)` then commit.
void write_atomically(const std::string& target, const std::function<void(const std::string&)>& writer);

/// Remove every registered temporary file (async-signal-unsafe parts avoided;
/// called from the signal handler installed by run_tool).
void remove_pending_temp_files() noexcept;

/// Lowercase extension of a path including compound ones: "x.nii.gz" -> ".nii.gz".
std::string file_extension(const std::string& path);

/// Check that a file exists and is readable. \throw IoError naming it.
void require_readable(const std::string& path);

}  // namespace pm
