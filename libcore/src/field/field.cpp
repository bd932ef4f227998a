#include "pm/field/field.h"

#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace pm {

struct ValueBounds::Blocks {
  // A block's lo and hi floats in one word (lo in the low half), so a reader
  // sees both or neither; kUnset (two all-ones NaNs, which no computation
  // produces) until computed.
  static constexpr std::uint64_t kUnset = ~std::uint64_t(0);
  Fill fill;
  std::unique_ptr<std::atomic<std::uint64_t>[]> word;
  Blocks(std::size_t n, Fill f) : fill(std::move(f)), word(new std::atomic<std::uint64_t>[n]) {
    for (std::size_t b = 0; b < n; ++b) word[b].store(kUnset, std::memory_order_relaxed);
  }
  void get(std::size_t b, float& lo, float& hi) const {
    std::uint64_t w = word[b].load(std::memory_order_relaxed);
    if (w == kUnset) {
      fill(b, lo, hi);
      std::uint32_t l, h;
      std::memcpy(&l, &lo, 4);
      std::memcpy(&h, &hi, 4);
      w = std::uint64_t(h) << 32 | l;
      if (w == kUnset) w = 0x7FC000007FC00000ull;  // (NaN, NaN) under another pattern
      word[b].store(w, std::memory_order_relaxed);  // racing threads store the same value
    }
    const std::uint32_t l = std::uint32_t(w), h = std::uint32_t(w >> 32);
    std::memcpy(&lo, &l, 4);
    std::memcpy(&hi, &h, 4);
  }
};

ValueBounds::ValueBounds(std::size_t blocks, Fill fill) : blocks_(std::make_shared<Blocks>(blocks, std::move(fill))) {}

bool ValueBounds::at(const Vec3& x, double& l, double& h) const {
  // The same arithmetic as VolumeField's own index mapping, so a point on a
  // block's edge falls in the block whose samples the field reads.
  const Vec3 t = to_index * (x - origin);
  const double ta[3] = {t.x, t.y, t.z};
  std::size_t b = 0, stride = 1;
  for (int a = 0; a < 3; ++a) {
    if (!(ta[a] >= 0.0 && ta[a] <= double(n[a] - 1))) return false;
    int i = static_cast<int>(ta[a]);  // t >= 0: truncation is floor
    b += std::size_t(i / block) * stride;
    stride *= std::size_t(nb[a]);
  }
  float lo, hi;
  blocks_->get(b, lo, hi);
  l = negate_ ? -double(hi) : lo;
  h = negate_ ? -double(lo) : hi;
  return true;
}

ValueBounds ValueBounds::negated() const {
  ValueBounds r = *this;
  r.negate_ = !negate_;
  return r;
}

std::shared_ptr<const ValueBounds> ScalarField::value_bounds(int) const { return nullptr; }

std::shared_ptr<const ValueBounds> NegatedField::value_bounds(int block) const {
  auto b = f_.value_bounds(block);
  if (!b) return nullptr;
  return std::make_shared<const ValueBounds>(b->negated());
}

void ScalarField::value_batch(const Vec3* x, std::size_t n, double* f) const {
  for (std::size_t k = 0; k < n; ++k) f[k] = value(x[k]);
}

void ScalarField::value_gradient_batch(const Vec3* x, std::size_t n, double* f, Vec3* grad) const {
  for (std::size_t k = 0; k < n; ++k) f[k] = value_gradient(x[k], grad[k]);
}

void ScalarField::evaluate_batch(const Vec3* x, std::size_t n, double* f, Vec3* grad, Mat3* hess) const {
  for (std::size_t k = 0; k < n; ++k) f[k] = evaluate(x[k], grad[k], hess[k]);
}

bool material_below_iso(const ScalarField& f, double iso) {
  const Box d = f.domain();
  int above = 0;
  for (int c = 0; c < 8; ++c) {
    const Vec3 x((c & 1) ? d.hi.x : d.lo.x, (c & 2) ? d.hi.y : d.lo.y, (c & 4) ? d.hi.z : d.lo.z);
    above += f.value(x) > iso;
  }
  return above >= 4;
}

double NegatedField::value_gradient(const Vec3& x, Vec3& grad) const {
  const double v = f_.value_gradient(x, grad);
  grad = -grad;
  return -v;
}

double NegatedField::evaluate(const Vec3& x, Vec3& grad, Mat3& hess) const {
  const double v = f_.evaluate(x, grad, hess);
  grad = -grad;
  hess = hess * -1.0;
  return -v;
}

void NegatedField::value_batch(const Vec3* x, std::size_t n, double* f) const {
  f_.value_batch(x, n, f);
  for (std::size_t k = 0; k < n; ++k) f[k] = -f[k];
}

void NegatedField::value_gradient_batch(const Vec3* x, std::size_t n, double* f, Vec3* grad) const {
  f_.value_gradient_batch(x, n, f, grad);
  for (std::size_t k = 0; k < n; ++k) {
    f[k] = -f[k];
    grad[k] = -grad[k];
  }
}

void NegatedField::evaluate_batch(const Vec3* x, std::size_t n, double* f, Vec3* grad, Mat3* hess) const {
  f_.evaluate_batch(x, n, f, grad, hess);
  for (std::size_t k = 0; k < n; ++k) {
    f[k] = -f[k];
    grad[k] = -grad[k];
    hess[k] = hess[k] * -1.0;
  }
}

}  // namespace pm
