#include "physics/efg/rotation_extraction.hpp"

#include "physics/core/cpu_features.hpp"
#include "physics/efg/llt3.hpp"
#include "physics/fem/corotational_fem.hpp"

#include <atomic>
#include <cmath>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define INCISE_ROTATION_AVX2 1
#include <immintrin.h>
#endif

namespace incise::physics {

namespace {

using Quaternion = Eigen::Quaterniond;

constexpr int max_iterations = 24;

// One iteration: updates q, false once it has settled (no step left, or one below 1e-8, whose
// remaining error is of order angle^2).
[[gnu::always_inline]] inline bool iterate(const Mat3& f, Quaternion& q) {
  const Mat3 r = q.toRotationMatrix();
  const Mat3 n = f * r.transpose();
  const Vec3 g(n(2, 1) - n(1, 2), n(0, 2) - n(2, 0), n(1, 0) - n(0, 1));
  const Mat3 hessian = n.trace() * Mat3::Identity() - 0.5 * (n + n.transpose());
  Vec3 omega;
  if (!llt3_solve(hessian, g, omega)) omega = g / (std::abs(n.trace()) + 1e-9);
  const double angle = omega.norm();
  if (!(angle > 0)) return false;
  q = Quaternion(Eigen::AngleAxisd(angle, omega / angle)) * q;
  q.normalize();
  return !(angle < 1e-8);
}

Quaternion polar(const Mat3& f) { return Quaternion(CorotationalTetFem::polar_rotation(f)).normalized(); }

void interleaved(const Mat3* f, Quaternion* q, int count) {
  bool running[rotation_lanes];
  int left = 0;
  for (int i = 0; i < count; ++i) left += (running[i] = f[i].allFinite()) ? 1 : 0;
  for (int iteration = 0; iteration < max_iterations && left > 0; ++iteration) {
    for (int i = 0; i < count; ++i) {
      if (running[i] && !iterate(f[i], q[i])) {
        running[i] = false;
        --left;
      }
    }
  }
  for (int i = 0; i < count; ++i)
    if (running[i]) q[i] = polar(f[i]);
}

#if defined(INCISE_ROTATION_AVX2)
// iterate() on 4 lanes. Each line is one of the scalar code's operations as Eigen 3.4 evaluates
// it with SSE2 (test_efg's RotationExtraction compares the bits): a 3 x 3 product's rows 0 and 1
// as (a0 + a1) + a2 (a packet of two rows accumulated along k), its row 2 and a trace as
// a0 + (a1 + a2) (an unrolled scalar reduction), a Vec3's squared norm as
// (a0 + a1) + a2 (a packet of two, then the tail), the quaternion product and squared norm as
// Eigen's SSE2 kernels pair the coefficients. No FMA: the scalar code has none.
struct Lanes {
  __m256d x, y, z, w;
};

__attribute__((target("avx2"))) inline __m256d add(__m256d a, __m256d b) { return _mm256_add_pd(a, b); }
__attribute__((target("avx2"))) inline __m256d sub(__m256d a, __m256d b) { return _mm256_sub_pd(a, b); }
__attribute__((target("avx2"))) inline __m256d mul(__m256d a, __m256d b) { return _mm256_mul_pd(a, b); }
__attribute__((target("avx2"))) inline __m256d div(__m256d a, __m256d b) { return _mm256_div_pd(a, b); }

// Whether this libm's sincos returns (x, 1) for 0 < x < 2^-27, as glibc's and musl's code and
// any correctly rounded one do: probed once, the shortcut is off if any probe differs.
bool libm_tiny_sincos() {
  static const bool exact = [] {
    for (double x : {0x1p-27 * (1 - 0x1p-52), 0x1.8p-28, 1e-9, 3.7e-12, 1e-300, 0x1p-1074}) {
      const double sine = std::sin(x), cosine = std::cos(x);
      if (sine != x || cosine != 1.0) return false;
    }
    return true;
  }();
  return exact;
}

// One vector of 4 lanes: their F, q and which are still iterating (all bits set).
struct LaneSet {
  __m256d fm[9];
  Lanes quat;
  __m256d running;
};

__attribute__((target("avx2"))) void load(const Mat3* f, const Quaternion* q, LaneSet& set) {
  for (int i = 0; i < 9; ++i) set.fm[i] = _mm256_setr_pd(f[0](i), f[1](i), f[2](i), f[3](i));
  set.quat = {_mm256_setr_pd(q[0].x(), q[1].x(), q[2].x(), q[3].x()), _mm256_setr_pd(q[0].y(), q[1].y(), q[2].y(), q[3].y()),
              _mm256_setr_pd(q[0].z(), q[1].z(), q[2].z(), q[3].z()), _mm256_setr_pd(q[0].w(), q[1].w(), q[2].w(), q[3].w())};
  bool lane_running[4];
  for (int i = 0; i < 4; ++i) lane_running[i] = f[i].allFinite();
  set.running = _mm256_castsi256_pd(_mm256_setr_epi64x(lane_running[0] ? -1 : 0, lane_running[1] ? -1 : 0,
                                                       lane_running[2] ? -1 : 0, lane_running[3] ? -1 : 0));
}

// iterate() on the set's running lanes.
__attribute__((target("avx2"), always_inline)) inline void iterate(LaneSet& set) {
  const __m256d* fm = set.fm;
  auto F = [&](int row, int column) -> const __m256d& { return fm[3 * column + row]; };
  Lanes& quat = set.quat;
  __m256d& running = set.running;
  const __m256d one = _mm256_set1_pd(1.0), two = _mm256_set1_pd(2.0), half = _mm256_set1_pd(0.5), zero_d = _mm256_setzero_pd();
  const __m256d sign = _mm256_set1_pd(-0.0);
  // r = q.toRotationMatrix() (Eigen's formulas).
  const __m256d tx = mul(two, quat.x), ty = mul(two, quat.y), tz = mul(two, quat.z);
  const __m256d twx = mul(tx, quat.w), twy = mul(ty, quat.w), twz = mul(tz, quat.w);
  const __m256d txx = mul(tx, quat.x), txy = mul(ty, quat.x), txz = mul(tz, quat.x);
  const __m256d tyy = mul(ty, quat.y), tyz = mul(tz, quat.y), tzz = mul(tz, quat.z);
  __m256d r[3][3];
  r[0][0] = sub(one, add(tyy, tzz));
  r[0][1] = sub(txy, twz);
  r[0][2] = add(txz, twy);
  r[1][0] = add(txy, twz);
  r[1][1] = sub(one, add(txx, tzz));
  r[1][2] = sub(tyz, twx);
  r[2][0] = sub(txz, twy);
  r[2][1] = add(tyz, twx);
  r[2][2] = sub(one, add(txx, tyy));
  // n = f r^T: n(i, j) = sum_k f(i, k) r(j, k).
  __m256d n[3][3];
  for (int j = 0; j < 3; ++j) {
    for (int i = 0; i < 2; ++i) n[i][j] = add(add(mul(F(i, 0), r[j][0]), mul(F(i, 1), r[j][1])), mul(F(i, 2), r[j][2]));
    n[2][j] = add(mul(F(2, 0), r[j][0]), add(mul(F(2, 1), r[j][1]), mul(F(2, 2), r[j][2])));
  }
  const __m256d g0 = sub(n[2][1], n[1][2]), g1 = sub(n[0][2], n[2][0]), g2 = sub(n[1][0], n[0][1]);
  const __m256d trace = add(n[0][0], add(n[1][1], n[2][2]));
  // tr(N) I - 0.5 (N + N^T), the lower triangle llt3_solve reads.
  const __m256d diagonal = mul(trace, one), off = mul(trace, zero_d);
  const __m256d h00 = sub(diagonal, mul(half, add(n[0][0], n[0][0])));
  const __m256d h10 = sub(off, mul(half, add(n[1][0], n[0][1])));
  const __m256d h20 = sub(off, mul(half, add(n[2][0], n[0][2])));
  const __m256d h11 = sub(diagonal, mul(half, add(n[1][1], n[1][1])));
  const __m256d h21 = sub(off, mul(half, add(n[2][1], n[1][2])));
  const __m256d h22 = sub(diagonal, mul(half, add(n[2][2], n[2][2])));
  // llt3_solve, with its failures (a pivot <= 0) as a mask.
  __m256d failed = _mm256_cmp_pd(h00, zero_d, _CMP_LE_OQ);
  const __m256d l00 = _mm256_sqrt_pd(h00);
  const __m256d l10 = div(h10, l00), l20 = div(h20, l00);
  const __m256d l11_squared = sub(h11, mul(l10, l10));
  failed = _mm256_or_pd(failed, _mm256_cmp_pd(l11_squared, zero_d, _CMP_LE_OQ));
  const __m256d l11 = _mm256_sqrt_pd(l11_squared);
  const __m256d l21 = div(sub(h21, mul(l20, l10)), l11);
  const __m256d l22_squared = sub(h22, add(mul(l20, l20), mul(l21, l21)));
  failed = _mm256_or_pd(failed, _mm256_cmp_pd(l22_squared, zero_d, _CMP_LE_OQ));
  const __m256d l22 = _mm256_sqrt_pd(l22_squared);
  __m256d y0 = div(g0, l00);
  __m256d y1 = div(sub(g1, mul(l10, y0)), l11);
  __m256d y2 = div(sub(g2, add(mul(l20, y0), mul(l21, y1))), l22);
  y2 = div(y2, l22);
  y1 = div(sub(y1, mul(l21, y2)), l11);
  y0 = div(sub(y0, add(mul(l10, y1), mul(l20, y2))), l00);
  // Otherwise g / (|tr N| + 1e-9).
  const __m256d scale = add(_mm256_andnot_pd(sign, trace), _mm256_set1_pd(1e-9));
  const __m256d o0 = _mm256_blendv_pd(y0, div(g0, scale), failed);
  const __m256d o1 = _mm256_blendv_pd(y1, div(g1, scale), failed);
  const __m256d o2 = _mm256_blendv_pd(y2, div(g2, scale), failed);
  const __m256d angle = _mm256_sqrt_pd(add(add(mul(o0, o0), mul(o1, o1)), mul(o2, o2)));
  // Lanes with no step left keep q and stop.
  const __m256d stepping = _mm256_and_pd(running, _mm256_cmp_pd(angle, zero_d, _CMP_GT_OQ));
  const int stepping_lanes = _mm256_movemask_pd(stepping);
  if (stepping_lanes == 0) {
    running = zero_d;
    return;
  }
  const __m256d a0 = div(o0, angle), a1 = div(o1, angle), a2 = div(o2, angle);
  // Quaternion(AngleAxisd(angle, axis)): w = cos(angle / 2), vec = sin(angle / 2) axis.
  // Below 2^-27 (a settling step's) sincos gives sin x = x, cos x = 1 (libm_tiny_sincos), without the call.
  const __m256d halves_v = mul(half, angle);
  const int tiny = libm_tiny_sincos() ? _mm256_movemask_pd(_mm256_cmp_pd(halves_v, _mm256_set1_pd(0x1p-27), _CMP_LT_OQ)) : 0;
  alignas(32) double halves[4], sines[4], cosines[4] = {1, 1, 1, 1};
  _mm256_store_pd(halves, halves_v);
  _mm256_store_pd(sines, halves_v);
  for (int i = 0; i < 4; ++i)
    if ((stepping_lanes & ~tiny) & (1 << i)) {
      // As Eigen's AngleAxis conversion calls them (the compiler makes both one sincos there and here).
      sines[i] = std::sin(halves[i]);
      cosines[i] = std::cos(halves[i]);
    }
  const __m256d s = _mm256_load_pd(sines);
  const Lanes a{mul(s, a0), mul(s, a1), mul(s, a2), _mm256_load_pd(cosines)};
  const Lanes& b = quat;
  // a * b as Eigen's SSE2 quat_product pairs it.
  Lanes product;
  product.x = sub(add(mul(a.w, b.x), mul(a.y, b.z)), sub(mul(a.z, b.y), mul(a.x, b.w)));
  product.y = add(add(mul(a.w, b.y), mul(a.y, b.w)), sub(mul(a.z, b.x), mul(a.x, b.z)));
  product.z = add(sub(mul(a.w, b.z), mul(a.y, b.x)), add(mul(a.z, b.w), mul(a.x, b.y)));
  product.w = sub(sub(mul(a.w, b.w), mul(a.y, b.y)), add(mul(a.z, b.z), mul(a.x, b.x)));
  // normalize(): the squared norm as (x^2 + z^2) + (y^2 + w^2), each coefficient divided by its root when positive.
  const __m256d squared = add(add(mul(product.x, product.x), mul(product.z, product.z)),
                              add(mul(product.y, product.y), mul(product.w, product.w)));
  const __m256d norm = _mm256_sqrt_pd(squared);
  const __m256d positive = _mm256_cmp_pd(squared, zero_d, _CMP_GT_OQ);
  product.x = _mm256_blendv_pd(product.x, div(product.x, norm), positive);
  product.y = _mm256_blendv_pd(product.y, div(product.y, norm), positive);
  product.z = _mm256_blendv_pd(product.z, div(product.z, norm), positive);
  product.w = _mm256_blendv_pd(product.w, div(product.w, norm), positive);
  quat.x = _mm256_blendv_pd(quat.x, product.x, stepping);
  quat.y = _mm256_blendv_pd(quat.y, product.y, stepping);
  quat.z = _mm256_blendv_pd(quat.z, product.z, stepping);
  quat.w = _mm256_blendv_pd(quat.w, product.w, stepping);
  // Settled below 1e-8 (the comparison false for NaN, as !(angle < 1e-8) is true there).
  running = _mm256_andnot_pd(_mm256_cmp_pd(angle, _mm256_set1_pd(1e-8), _CMP_LT_OQ), stepping);
}

__attribute__((target("avx2"))) void store(const LaneSet& set, const Mat3* f, Quaternion* q) {
  alignas(32) double xs[4], ys[4], zs[4], ws[4];
  _mm256_store_pd(xs, set.quat.x);
  _mm256_store_pd(ys, set.quat.y);
  _mm256_store_pd(zs, set.quat.z);
  _mm256_store_pd(ws, set.quat.w);
  const int still_running = _mm256_movemask_pd(set.running);
  for (int i = 0; i < 4; ++i) q[i] = still_running & (1 << i) ? polar(f[i]) : Quaternion(ws[i], xs[i], ys[i], zs[i]);
}

// Two sets iterate side by side: one set's iteration is a chain of dependent divisions, square
// roots and sincos calls; the other's fills the core meanwhile.
constexpr int lane_sets = rotation_lanes / 4;

__attribute__((target("avx2"))) void avx2_extract(const Mat3* f, Quaternion* q) {
  LaneSet sets[lane_sets];
  for (int v = 0; v < lane_sets; ++v) load(f + 4 * v, q + 4 * v, sets[v]);
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    bool any = false;
    for (int v = 0; v < lane_sets; ++v) {
      if (_mm256_movemask_pd(sets[v].running) == 0) continue;
      any = true;
      iterate(sets[v]);
    }
    if (!any) break;
  }
  for (int v = 0; v < lane_sets; ++v) store(sets[v], f + 4 * v, q + 4 * v);
}

#endif

std::atomic<bool> vectorised_allowed{true};

}  // namespace

Quaternion extract_rotation(const Mat3& f, Quaternion q) {
  if (!f.allFinite()) return q;
  for (int iteration = 0; iteration < max_iterations; ++iteration)
    if (!iterate(f, q)) return q;
  return polar(f);
}

bool rotation_extraction_vectorised() {
#if defined(INCISE_ROTATION_AVX2)
  return vectorised_allowed.load(std::memory_order_relaxed) && cpu_has_avx2();
#else
  return false;
#endif
}

void set_rotation_extraction_vectorised(bool allowed) { vectorised_allowed.store(allowed, std::memory_order_relaxed); }

void extract_rotations(const Mat3* f, Quaternion* q, int count) {
#if defined(INCISE_ROTATION_AVX2)
  if (count == rotation_lanes && rotation_extraction_vectorised()) return avx2_extract(f, q);
#endif
  interleaved(f, q, count);
}

}  // namespace incise::physics
