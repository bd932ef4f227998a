#pragma once
// Typed exceptions thrown by libcore. Library code never prints or exits;
// pm::run_tool maps these to one stderr line and an exit code.
#include <stdexcept>
#include <string>

namespace pm {

/// Base of every particlemesh error.
struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Bad input data (unreadable header, wrong dimension, NaN voxels, ...): exit 1.
struct InputError : Error {
  using Error::Error;
};

/// File system or library I/O failure (missing file, unwritable folder): exit 1.
struct IoError : Error {
  using Error::Error;
};

/// Bad option value found after parsing (s <= 0, unknown implicit name): exit 2.
struct UsageError : Error {
  using Error::Error;
};

/// A checker found the output wanting (meshstats --require): exit 3.
struct CheckFailed : Error {
  using Error::Error;
};

/// A front end asked the run to stop (pm::check_cancelled; e.g. Ctrl-C in
/// the Python module). Tools never see it: they install no cancel hook.
struct Cancelled : Error {
  using Error::Error;
};

/// Quote a file name for messages: "name".
std::string quote(const std::string& s);

/// A number for messages, as a user would type it (%g: "3", "0.5", "4e+09").
std::string format_number(double v);

}  // namespace pm
