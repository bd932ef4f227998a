#include "pm/volume/labels.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <sstream>
#include <unordered_map>

#include "pm/base/error.h"
#include "pm/volume/tighten.h"

namespace pm {
namespace {
std::int64_t parse_int(const std::string& tok, const std::string& context) {
  std::size_t pos = 0;
  long long v = 0;
  try {
    v = std::stoll(tok, &pos);
  } catch (const std::exception&) {
    pos = 0;
  }
  if (tok.empty() || pos != tok.size())
    throw UsageError(context + ": \"" + tok + "\" is not an integer label");
  return v;
}

std::vector<std::string> split(const std::string& s, const std::string& seps) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : s) {
    if (seps.find(c) != std::string::npos) {
      if (!cur.empty()) out.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  if (!cur.empty()) out.push_back(cur);
  return out;
}
}  // namespace

std::vector<std::int64_t> parse_label_list(const std::string& spec) {
  std::vector<std::int64_t> out;
  for (const std::string& tok : split(spec, ", ")) {
    const auto dash = tok.find('-', 1);
    if (dash != std::string::npos) {
      const std::int64_t a = parse_int(tok.substr(0, dash), "label list"),
                         b = parse_int(tok.substr(dash + 1), "label list");
      if (b < a || b - a > 1000000) throw UsageError("label list: bad range \"" + tok + "\"; expected a-b with a <= b");
      for (std::int64_t v = a; v <= b; ++v) out.push_back(v);
    } else {
      out.push_back(parse_int(tok, "label list"));
    }
  }
  if (out.empty()) throw UsageError("label list \"" + spec + "\" is empty; expected e.g. \"2,41\" or \"2-5,7\"");
  return out;
}

std::vector<MergeRule> parse_merge_spec(const std::string& spec) {
  std::vector<MergeRule> rules;
  for (const std::string& r : split(spec, " ;")) {
    const auto colon = r.find(':');
    if (colon == std::string::npos || colon == 0 || colon + 1 == r.size())
      throw UsageError("merge rule \"" + r + "\" is malformed; expected \"a,b,...:target\", e.g. \"1,2:1 3,4:2\"");
    MergeRule m;
    m.from = parse_label_list(r.substr(0, colon));
    m.to = parse_int(r.substr(colon + 1), "merge rule \"" + r + "\"");
    rules.push_back(std::move(m));
  }
  if (rules.empty()) throw UsageError("merge spec is empty; expected e.g. \"1,2:1 3,4:2\"");
  std::set<std::int64_t> seen;
  for (const auto& r : rules)
    for (auto v : r.from)
      if (!seen.insert(v).second)
        throw UsageError("merge spec: label " + std::to_string(v) + " appears in two rules; expected each label once");
  return rules;
}

void require_labels(const Volume& v, const std::string& what) {
  if (is_integer(v.type())) return;
  const std::size_t n = v.count();
  for (std::size_t i = 0; i < n; ++i) {
    const double x = v.get(i);
    if (!std::isfinite(x) || x != std::floor(x) || std::fabs(x) > 9e15) {
      std::ostringstream m;
      m << what << ": voxel " << i << " has value " << x << "; expected integer labels (a label map)";
      throw InputError(m.str());
    }
  }
}

std::map<std::int64_t, std::size_t> label_counts(const Volume& v, std::size_t max_labels) {
  require_labels(v, "label_counts");
  std::unordered_map<std::int64_t, std::size_t> counts;
  const std::size_t n = v.count();
  // Label maps come in runs along x: count a run at once.
  std::int64_t last = 0;
  std::size_t run = 0;
  auto flush = [&] {
    if (run == 0) return;
    counts[last] += run;
    if (counts.size() > max_labels)
      throw InputError("label_counts: more than " + std::to_string(max_labels) +
                       " distinct values; expected a label map");
  };
  visit_voxel_type(v.type(), [&](auto tag) {
    using T = decltype(tag);
    const T* p = v.data<T>();
    for (std::size_t i = 0; i < n; ++i) {
      const std::int64_t x = std::int64_t(static_cast<double>(p[i]));
      if (run > 0 && x == last) {
        ++run;
        continue;
      }
      flush();
      last = x;
      run = 1;
    }
    return 0;
  });
  flush();
  return {counts.begin(), counts.end()};
}

std::map<std::int64_t, std::size_t> border_label_counts(const Volume& v) {
  require_labels(v, "border_label_counts");
  const Dims& n = v.dims();
  std::map<std::int64_t, std::size_t> counts;
  for (std::size_t k = 0; k < n.nz; ++k)
    for (std::size_t j = 0; j < n.ny; ++j) {
      const bool face = k == 0 || k + 1 == n.nz || j == 0 || j + 1 == n.ny;
      const std::size_t step = face ? 1 : std::max<std::size_t>(n.nx - 1, 1);  // inner rows: both ends only
      for (std::size_t i = 0; i < n.nx; i += step) ++counts[std::int64_t(v.get(i, j, k))];
    }
  return counts;
}

BorderPadding border_padding(const Volume& v) {
  const auto border = border_label_counts(v);
  BorderPadding b;
  b.border_labels = border.size();
  std::size_t total = 0, best = 0;
  for (const auto& [l, c] : border) {
    total += c;
    if (c > best) {
      best = c;
      b.value = l;
    }
  }
  const Dims& n = v.dims();
  if (border.size() <= 1 || std::min(n.nx, std::min(n.ny, n.nz)) < kTightenMinVoxels) return b;
  b.pad = true;
  if (2 * best <= total) {
    b.new_label = true;
    b.value = label_counts(v).rbegin()->first + 1;
  }
  return b;
}

double pad_value_of(const Volume& v, const std::string& spec, const std::string& what) {
  if (spec == "auto") {
    require_labels(v, what);
    return double(border_padding(v).value);
  }
  if (spec == "new") {
    require_labels(v, what);
    return value_range(v).hi + 1;
  }
  double value = 0;
  try {
    std::size_t pos = 0;
    value = std::stod(spec, &pos);
    if (pos != spec.size() || !std::isfinite(value)) throw std::invalid_argument("");
  } catch (const std::exception&) {
    throw UsageError("--pad-value \"" + spec + "\": expected a finite number, \"new\" or \"auto\"");
  }
  return value;
}

Volume label_mask(const Volume& v, const std::vector<std::int64_t>& which, const std::string& what) {
  require_labels(v, what);
  const std::set<std::int64_t> want(which.begin(), which.end());
  Volume out(VoxelType::u8, v.dims(), v.geometry());
  std::uint8_t* o = out.data<std::uint8_t>();
  const std::size_t n = v.count();
  std::size_t inside = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const bool in = want.count(std::int64_t(v.get(i))) > 0;
    o[i] = in;
    inside += in;
  }
  if (inside == 0) {
    std::ostringstream m;
    m << what << ": none of the labels";
    for (auto w : which) m << " " << w;
    m << " occurs; labels present:";
    std::size_t shown = 0;
    for (const auto& [l, c] : label_counts(v)) {
      if (shown++ == 32) { m << " ..."; break; }
      m << " " << l;
      (void)c;
    }
    throw InputError(m.str());
  }
  return out;
}

Volume merge_labels(const Volume& v, const std::vector<MergeRule>& rules) {
  require_labels(v, "merge_labels");
  std::unordered_map<std::int64_t, std::int64_t> map;
  std::int64_t lo = std::numeric_limits<std::int64_t>::max(), hi = std::numeric_limits<std::int64_t>::min();
  for (const auto& r : rules) {
    for (auto f : r.from) map[f] = r.to;
    lo = std::min(lo, r.to);
    hi = std::max(hi, r.to);
  }
  VoxelType t = v.type();
  const bool fits = !is_integer(t) || [&] {
    Volume probe(t, Dims{1, 1, 1});
    probe.set(0, double(lo));
    if (probe.get(0) != double(lo)) return false;
    probe.set(0, double(hi));
    return probe.get(0) == double(hi);
  }();
  if (!fits) t = VoxelType::i32;
  Volume out = t == v.type() ? v : v.converted(t);
  const std::size_t n = v.count();
  // One lookup per run of equal labels; a relabelled run is written as its
  // first voxel (set() converts) copied along the run.
  visit_voxel_type(v.type(), [&](auto tag) {
    using T = decltype(tag);
    const T* p = v.data<T>();
    for (std::size_t i = 0; i < n;) {
      const std::int64_t x = std::int64_t(static_cast<double>(p[i]));
      std::size_t e = i + 1;
      while (e < n && std::int64_t(static_cast<double>(p[e])) == x) ++e;
      const auto it = map.find(x);
      if (it != map.end()) {
        out.set(i, double(it->second));
        visit_voxel_type(out.type(), [&](auto otag) {
          using U = decltype(otag);
          U* q = out.data<U>();
          std::fill(q + i + 1, q + e, q[i]);
          return 0;
        });
      }
      i = e;
    }
    return 0;
  });
  return out;
}

Volume drop_small_labels(const Volume& v, std::size_t min_voxels, std::vector<std::int64_t>* dropped) {
  const auto counts = label_counts(v, std::size_t(1) << 24);
  std::set<std::int64_t> drop;
  for (const auto& [l, c] : counts)
    if (c < min_voxels) drop.insert(l);
  if (drop.size() == counts.size())
    throw InputError("drop_small_labels: every label has fewer than " + std::to_string(min_voxels) +
                     " voxels; expected at least one label to keep");
  if (dropped) dropped->insert(dropped->end(), drop.begin(), drop.end());
  Volume out = v;
  if (drop.empty()) return out;
  const Dims& d = v.dims();
  const std::size_t n = v.count();
  std::vector<std::uint8_t> open(n);
  std::vector<std::size_t> todo;
  visit_voxel_type(v.type(), [&](auto tag) {
    using T = decltype(tag);
    const T* p = v.data<T>();
    bool dropped_last = false;
    std::int64_t prev = 0;
    for (std::size_t c = 0; c < n; ++c) {
      const std::int64_t x = std::int64_t(static_cast<double>(p[c]));
      if (c == 0 || x != prev) dropped_last = drop.count(x) > 0;  // one lookup per run
      prev = x;
      if (dropped_last) {
        open[c] = 1;
        todo.push_back(c);
      }
    }
    return 0;
  });
  // A voxel's label, as it stands: the output holds every decision so far
  // (no int64 copy of the whole map: 272 MB on the frog, for a few voxels).
  auto lab = [&](std::size_t q) { return std::int64_t(out.get(q)); };
  // Grow the kept labels into the dropped voxels, one face layer at a time.
  while (!todo.empty()) {
    std::vector<std::pair<std::size_t, std::int64_t>> decided;
    std::vector<std::size_t> rest;
    for (std::size_t c : todo) {
      const std::size_t i = c % d.nx, j = (c / d.nx) % d.ny, k = c / (d.nx * d.ny);
      std::map<std::int64_t, int> votes;
      auto vote = [&](std::size_t q) {
        if (!open[q]) ++votes[lab(q)];
      };
      if (i > 0) vote(c - 1);
      if (i + 1 < d.nx) vote(c + 1);
      if (j > 0) vote(c - d.nx);
      if (j + 1 < d.ny) vote(c + d.nx);
      if (k > 0) vote(c - d.nx * d.ny);
      if (k + 1 < d.nz) vote(c + d.nx * d.ny);
      if (votes.empty()) {
        rest.push_back(c);
        continue;
      }
      std::int64_t best = votes.begin()->first;
      int bn = 0;
      for (const auto& [l, nv] : votes)
        if (nv > bn) {
          best = l;
          bn = nv;
        }
      decided.emplace_back(c, best);
    }
    for (const auto& [c, l] : decided) {
      open[c] = 0;
      out.set(c, double(l));
    }
    todo.swap(rest);
  }
  return out;
}

}  // namespace pm
