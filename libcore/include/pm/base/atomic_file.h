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

/// Deferred commits: one run, all outputs or none. While deferral is on (the
/// tools' frame, cli/run_tool, turns it on around each tool's body), commit()
/// only checks that the temporary file exists and keeps it registered; the
/// renames happen together in commit_deferred(), with a signal that arrives
/// meanwhile held back until the last rename is done. An interrupted or failed
/// run thus leaves none of its outputs, not only none of its temporary files.
void defer_commits(bool on);
/// Rename every deferred temporary file onto its target, in commit order.
/// Returns the number of a SIGINT/SIGTERM that arrived during the renames (0 if
/// none); the caller re-raises it. \throw IoError when a rename fails (the
/// rest are then discarded).
int commit_deferred();
/// Delete every deferred temporary file (on a failed run).
void discard_deferred() noexcept;
/// For the signal handler: true (and the signal kept for commit_deferred) when
/// the deferred renames are under way, so the handler must return.
bool hold_signal_during_commit(int sig) noexcept;

/// Remove every registered temporary file (async-signal-unsafe parts avoided;
/// called from the signal handler installed by run_tool).
void remove_pending_temp_files() noexcept;

/// Lowercase extension of a path including compound ones: "x.nii.gz" -> ".nii.gz".
std::string file_extension(const std::string& path);

/// Check that a file exists and is readable. \throw IoError naming it.
void require_readable(const std::string& path);

}  // namespace pm
