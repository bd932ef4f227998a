#include "pm/cli/energy_option.h"

#include <array>
#include <utility>
#include <vector>

#include "pm/base/error.h"

namespace pm {
namespace {

constexpr std::array<std::pair<const char*, ParticleEnergy>, 2> kEnergies = {
    {{"cotangent", ParticleEnergy::cotangent}, {"radial", ParticleEnergy::radial}}};

constexpr std::array<std::pair<const char*, StepControl>, 2> kStepControls = {
    {{"quadratic", StepControl::quadratic}, {"factor", StepControl::factor}}};

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

CLI::Option* add_step_options(CLI::App& app, StepControl& control, double& factor, const std::string& note) {
  std::vector<std::string> names;
  for (const auto& c : kStepControls) names.emplace_back(c.first);
  CLI::Option* opt = app.add_option_function<std::string>(
         "--step-control",
         [&control](const std::string& name) {
           for (const auto& c : kStepControls)
             if (name == c.first) control = c.second;
         },
         "Adaptive step (SPEC 3): quadratic = fit a parabola to each trial's energy and step to 1.75x its "
         "minimum, within a factor --step-factor; factor = the dissertation's rule, x --step-factor after a "
         "first-try acceptance, / after a rejection. " + note)
      ->check(CLI::IsMember(names))
      ->default_str(step_control_name(control));
  app.add_option("--step-factor", factor,
                 "Largest change of a particle's step after one trial (> 1; the dissertation's 10)")
      ->capture_default_str();
  return opt;
}

const char* step_control_name(StepControl c) {
  for (const auto& s : kStepControls)
    if (c == s.second) return s.first;
  return "?";
}

}  // namespace pm
