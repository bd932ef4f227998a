#include "pm/cli/energy_option.h"

#include <array>
#include <utility>

#include "pm/base/error.h"

namespace pm {
namespace {

constexpr std::array<std::pair<const char*, ParticleEnergy>, 2> kEnergies = {
    {{"cotangent", ParticleEnergy::cotangent}, {"radial", ParticleEnergy::radial}}};

}  // namespace

void add_energy_option(CLI::App& app, std::string& name) {
  std::vector<std::string> names;
  for (const auto& e : kEnergies) names.emplace_back(e.first);
  app.add_option("--energy", name, "Pair energy: cotangent or radial")
      ->check(CLI::IsMember(names))
      ->capture_default_str();
}

ParticleEnergy energy_named(const std::string& name) {
  for (const auto& e : kEnergies)
    if (name == e.first) return e.second;
  throw UsageError("--energy \"" + name + "\": expected cotangent or radial");
}

}  // namespace pm
