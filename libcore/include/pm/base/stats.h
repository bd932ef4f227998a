#pragma once
// Run statistics gathered by tools and written with --stats as one JSON object.
#include <nlohmann/json.hpp>
#include <string>

namespace pm {

using Json = nlohmann::json;

/// The stats object of the running tool; tools and ops add to it.
/// Fixed keys: "tool", "version"; tools add "inputs", "parameters",
/// "counts", "seconds".
Json& stats();

/// Record the duration of a stage: stats()["seconds"][name] += s.
void add_seconds(const std::string& name, double s);

/// Times a stage and records it on destruction; prints "stage ... 1.23 s" with -v.
class ScopedStage {
 public:
  explicit ScopedStage(std::string name);
  ~ScopedStage();

 private:
  std::string name_;
  double start_;
};

}  // namespace pm
