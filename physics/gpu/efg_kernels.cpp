#include "physics/gpu/efg_kernels.hpp"

#include <cctype>

namespace incise::physics::gpu {

namespace {

// Binding points. Row data and node data have fixed bindings; the vectors a kernel reads or
// writes are bound per dispatch to the slots 19 to 24.
const char* const kCommon = R"(
layout(std430, binding = 0) readonly buffer Neighbours { int neighbours[]; };
layout(std430, binding = 1) readonly buffer Gradients { real gradients[]; };
layout(std430, binding = 2) readonly buffer Values { real shape_values[]; };
layout(std430, binding = 3) readonly buffer Lengths { int lengths[]; };
layout(std430, binding = 4) readonly buffer Volumes { real volumes[]; };
layout(std430, binding = 5) readonly buffer RestGradients { real rest_gradients[]; };
layout(std430, binding = 6) buffer Rotations { real rotation_offsets[]; };
layout(std430, binding = 7) buffer Stresses { real stresses[]; };
layout(std430, binding = 8) readonly buffer Incidence { int incidence[]; };
layout(std430, binding = 9) readonly buffer IncidenceLengths { int incidence_lengths[]; };
layout(std430, binding = 10) readonly buffer Rest { real rest[]; };
layout(std430, binding = 11) readonly buffer Masses { real masses[]; };
layout(std430, binding = 12) readonly buffer Free { real free_dof[]; };
layout(std430, binding = 13) readonly buffer SpringIndex { int spring_index[]; };
layout(std430, binding = 14) readonly buffer SpringForce { real spring_force[]; };
layout(std430, binding = 15) readonly buffer SpringStiffness { real spring_stiffness[]; };
// 0 lambda, 1 mu, 2 dt, 3 alpha, 4 beta, 5 mass coefficient, 6 stiffness coefficient
layout(std430, binding = 16) readonly buffer Parameters { real parameters[]; };
layout(std430, binding = 17) buffer Scalars { real scalars[]; };
layout(std430, binding = 18) buffer Partials { real partials[]; };
layout(std430, binding = 19) buffer A { real va[]; };
layout(std430, binding = 20) buffer B { real vb[]; };
layout(std430, binding = 21) buffer C { real vc[]; };
layout(std430, binding = 22) buffer D { real vd[]; };
layout(std430, binding = 23) buffer E { real ve[]; };
layout(std430, binding = 24) buffer F { real vf[]; };
layout(std430, binding = 25) buffer Orientations { real orientations[]; };
layout(std430, binding = 26) buffer Flags { int flags[]; };

uniform int count;
uniform int stride;
uniform int incidence_stride;
uniform int mode;
uniform int slot0;
uniform int slot1;
// CG's state on the GPU (efg_step.cpp, solve_velocity_change): flags[1] its status (0 running,
// 1 converged, 2 non-finite, 3 p.Ap not positive, 4 at the iteration limit), flags[2] its
// iterations. Inside CG's loop (cg_gate 1) the iteration's kernels do nothing once the status is
// set, so the host can queue several iterations between read-backs and the iterate stops
// exactly where a CG checked after every iteration would have stopped.
uniform int cg_gate;
uniform int limit;
#define CG_DONE (cg_gate != 0 && flags[1] != 0)
#define THRESHOLD_SLOT 7

// Macros rather than functions, since GLSL cannot pass a buffer's array to a function; a
// kernel declares only the blocks it names (Mesa counts declared blocks against its limit of
// 16 per compute shader).
#define LOADA(i) vec3r(va[3 * (i)], va[3 * (i) + 1], va[3 * (i) + 2])
#define LOADB(i) vec3r(vb[3 * (i)], vb[3 * (i) + 1], vb[3 * (i) + 2])
#define GRADIENT(slot) vec3r(gradients[3 * (slot)], gradients[3 * (slot) + 1], gradients[3 * (slot) + 2])
// Row-major 3x3 blocks of 9 reals; GLSL matrices are column-major, so the block read in order
// is the transpose. Built by a constructor, not by writes at loop indices: NVIDIA's compiler
// cannot link a dmat3 written at a run-time index ("can't find __setVectorIndex").
#define LOAD_MATRIX(m, array, e) \
  m = transpose(mat3r(array[9 * (e)], array[9 * (e) + 1], array[9 * (e) + 2], array[9 * (e) + 3], \
                      array[9 * (e) + 4], array[9 * (e) + 5], array[9 * (e) + 6], array[9 * (e) + 7], \
                      array[9 * (e) + 8]))
#define STORE_MATRIX(array, e, m) \
  array[9 * (e)] = m[0].x; array[9 * (e) + 1] = m[1].x; array[9 * (e) + 2] = m[2].x; \
  array[9 * (e) + 3] = m[0].y; array[9 * (e) + 4] = m[1].y; array[9 * (e) + 5] = m[2].y; \
  array[9 * (e) + 6] = m[0].z; array[9 * (e) + 7] = m[1].z; array[9 * (e) + 8] = m[2].z
bool finite(real x) { return !isnan(x) && !isinf(x); }
bool finite3(vec3r v) { return finite(v.x) && finite(v.y) && finite(v.z); }
)";

// mode 0: elastic forces from the displacements in A; mode 1: K p for p in A.
// S_e = -V (I + W) sigma (forces) or +V (I + W) sigma (K p), sigma of grad u (file comment of
// efg_step.hpp: grad u = H + W^T (G0 + H), and for K p: P + W^T P).
const char* const kElementStress = R"(
void main() {
  int e = int(gl_GlobalInvocationID.x);
  if (e >= count || CG_DONE) return;
  int base = e * stride;
  int length = lengths[e];
  real volume = volumes[e];
  if (!(volume > real(0))) {
    for (int i = 0; i < 9; ++i) stresses[9 * e + i] = real(0);
    return;
  }
  int first = neighbours[base];
  vec3r reference = LOADA(first);
  mat3r h = mat3r(0);
  for (int k = 0; k < length; ++k) {
    vec3r d = LOADA(neighbours[base + k]) - reference;
    h += outerProduct(d, GRADIENT(base + k));  // column-major: h[c][r] = d[r] g[c]
  }
  mat3r w, rest_gradient;
  LOAD_MATRIX(w, rotation_offsets, e);
  LOAD_MATRIX(rest_gradient, rest_gradients, e);
  mat3r g = mode == 0 ? h + transpose(w) * (rest_gradient + h) : h + transpose(w) * h;
  mat3r strain = real(0.5) * (g + transpose(g));
  real trace = strain[0][0] + strain[1][1] + strain[2][2];
  mat3r sigma = real(2) * parameters[1] * strain + parameters[0] * trace * mat3r(1);
  mat3r s = (mode == 0 ? -volume : volume) * (sigma + w * sigma);
  STORE_MATRIX(stresses, e, s);
}
)";

// Per node: the sum of S_e grad phi over its incidence row, then by mode
//   0: C = B (external) + elastic + spring force
//   1: C = K A + K_spring A
//   2: C = free (mc M A + kc (K A + K_spring A))
const char* const kNodeGather = R"(
void main() {
  int n = int(gl_GlobalInvocationID.x);
  if (n >= count || CG_DONE) return;
  vec3r sum = vec3r(0);
  int length = incidence_lengths[n];
  for (int i = 0; i < length; ++i) {
    int slot = incidence[n * incidence_stride + i];
    int e = slot / stride;
    mat3r s;
    LOAD_MATRIX(s, stresses, e);
    sum += s * GRADIENT(slot);
  }
  int spring = spring_index[n];
  vec3r result;
  if (mode == 0) {
    result = LOADB(n) + sum;
    if (spring >= 0) result += vec3r(spring_force[3 * spring], spring_force[3 * spring + 1], spring_force[3 * spring + 2]);
  } else {
    vec3r p = LOADA(n);
    vec3r stiffness = sum;
    if (spring >= 0) {
      mat3r k;
      LOAD_MATRIX(k, spring_stiffness, spring);
      stiffness += k * p;
    }
    result = mode == 1 ? stiffness
                       : free_dof[n] * (parameters[5] * masses[n] * p + parameters[6] * stiffness);
  }
  vc[3 * n] = result.x;
  vc[3 * n + 1] = result.y;
  vc[3 * n + 2] = result.z;
}
)";

// C = 1 / diag(mc M + kc (K + K_spring)), 1 where that is not positive and finite.
// K_nn = V R (lambda g g^T + mu g g^T + mu |g|^2 I) R^T, whose diagonal needs only R g.
const char* const kDiagonal = R"(
void main() {
  int n = int(gl_GlobalInvocationID.x);
  if (n >= count) return;
  vec3r sum = vec3r(0);
  real lambda = parameters[0], mu = parameters[1];
  int length = incidence_lengths[n];
  for (int i = 0; i < length; ++i) {
    int slot = incidence[n * incidence_stride + i];
    int e = slot / stride;
    vec3r g = GRADIENT(slot);
    mat3r w;
    LOAD_MATRIX(w, rotation_offsets, e);
    vec3r turned = g + w * g;
    sum += volumes[e] * ((lambda + mu) * turned * turned + vec3r(mu * dot(g, g)));
  }
  int spring = spring_index[n];
  if (spring >= 0)
    sum += vec3r(spring_stiffness[9 * spring], spring_stiffness[9 * spring + 4], spring_stiffness[9 * spring + 8]);
  vec3r d = parameters[5] * masses[n] + parameters[6] * sum;
  vc[3 * n] = (d.x > real(0) && finite(d.x)) ? real(1) / d.x : real(1);
  vc[3 * n + 1] = (d.y > real(0) && finite(d.y)) ? real(1) / d.y : real(1);
  vc[3 * n + 2] = (d.z > real(0) && finite(d.z)) ? real(1) / d.z : real(1);
}
)";

// D = free dt (A - (dt + beta) B - alpha M C): A forces, B K v, C v.
const char* const kRightHandSide = R"(
void main() {
  int i = int(gl_GlobalInvocationID.x);
  if (i >= count) return;
  real dt = parameters[2];
  real b = dt * (va[i] - (dt + parameters[4]) * vb[i] - parameters[3] * (masses[i / 3] * vc[i]));
  vd[i] = free_dof[i / 3] > real(0) ? b : real(0);
}
)";

// r = free (b - A x), z = M^-1 r, p = z: A = A x, B = b, C = r, D = z, E = p, F = M^-1.
// The warm start x and its product Ax scaled by a = x.b / x.Ax (cg.cpp's
// scale_initial_guess: the multiple of the last step's dv nearest the solution in the A-norm,
// which keeps a CG stopped by the real-time budget from gaining energy). x.b = scalars[slot0],
// x.Ax = scalars[slot1]; nothing moves when x.Ax is not positive (a zero guess) or a is not
// finite. A = x, B = Ax.
const char* const kScaleGuess = R"(
void main() {
  int i = int(gl_GlobalInvocationID.x);
  if (i >= count) return;
  real curvature = scalars[slot1];
  real a = scalars[slot0] / curvature;
  if (!(curvature > real(0)) || !finite(a)) return;
  va[i] *= a;
  vb[i] *= a;
}
)";

const char* const kResidualInit = R"(
void main() {
  int i = int(gl_GlobalInvocationID.x);
  if (i >= count) return;
  real r = free_dof[i / 3] > real(0) ? vb[i] - va[i] : real(0);
  vc[i] = r;
  vd[i] = vf[i] * r;
  ve[i] = vd[i];
}
)";

// First pass of up to two dot products (A.B, and C.D when mode is 2): REDUCE_THREADS
// invocations each sum a fixed stride of the entries into partials[2 t + j]. No shared
// memory and no barrier(): llvmpipe runs barriers as coroutine switches per invocation,
// which made a shared-memory tree the slowest kernel of the step.
const char* const kDotPartial = R"(
void main() {
  int t = int(gl_GlobalInvocationID.x);
  if (CG_DONE) return;
  real s0 = real(0), s1 = real(0);
  for (int i = t; i < count; i += REDUCE_THREADS) {
    s0 += va[i] * vb[i];
    if (mode == 2) s1 += vc[i] * vd[i];
  }
  partials[2 * t] = s0;
  partials[2 * t + 1] = s1;
}
)";

// Second pass: one invocation sums the partials in order into scalars[slot0] (and slot1).
const char* const kDotFinal = R"(
void main() {
  if (gl_GlobalInvocationID.x != 0u || CG_DONE) return;
  real s0 = real(0), s1 = real(0);
  for (int t = 0; t < REDUCE_THREADS; ++t) {
    s0 += partials[2 * t];
    s1 += partials[2 * t + 1];
  }
  scalars[slot0] = s0;
  if (mode == 2) scalars[slot1] = s1;
}
)";

// x += s p, r -= s Ap, z = M^-1 r with s = scalars[slot1] / scalars[slot0] (r.z / p.Ap),
// skipped when p.Ap is not positive or s not finite (the host then stops, x unchanged).
// A = x, B = p, C = r, D = Ap, E = z, F = M^-1.
const char* const kCgUpdate = R"(
void main() {
  int i = int(gl_GlobalInvocationID.x);
  if (i >= count || CG_DONE) return;
  real curvature = scalars[slot0];
  real s = scalars[slot1] / curvature;
  if (!(curvature > real(0)) || !finite(s)) return;
  va[i] += s * vb[i];
  vc[i] -= s * vd[i];
  ve[i] = vf[i] * vc[i];
}
)";

// p = z + beta p, beta = scalars[slot1] / scalars[slot0] (new r.z / old r.z). A = z, B = p.
const char* const kCgDirection = R"(
void main() {
  int i = int(gl_GlobalInvocationID.x);
  if (i >= count || CG_DONE) return;
  real beta = scalars[slot1] / scalars[slot0];
  vb[i] = va[i] + beta * vb[i];
}
)";

// CG's stops, the host's checks moved to the GPU (cg.cpp's order): after an iteration (mode 0)
// p.Ap (scalars[slot0]) not finite or not positive ends CG before the iteration counts; then
// r.r (scalars[slot1]) at or below (tolerance |b|)^2 converges it, and the iteration limit
// (the maximum, or a recorded stop) ends it. Mode 1: the check of the first residual.
const char* const kCgCheck = R"(
void main() {
  if (gl_GlobalInvocationID.x != 0u || flags[1] != 0) return;
  if (mode == 0) {
    real curvature = scalars[slot0];
    if (!finite(curvature)) { flags[1] = 2; return; }
    if (!(curvature > real(0))) { flags[1] = 3; return; }
    flags[2] += 1;
  }
  real residual = scalars[slot1];
  if (!finite(residual)) flags[1] = 2;
  else if (residual <= scalars[THRESHOLD_SLOT]) flags[1] = 1;
  else if (mode == 0 && flags[2] >= limit) flags[1] = 4;
}
)";

// Per node: C (v next) = free (B (v) + D (dv)), E (u next) = free ? A (u) + dt C : A.
const char* const kIntegrate = R"(
void main() {
  int i = int(gl_GlobalInvocationID.x);
  if (i >= count) return;
  bool is_free = free_dof[i / 3] > real(0);
  real v = is_free ? vb[i] + vd[i] : real(0);
  vc[i] = v;
  ve[i] = is_free ? va[i] + parameters[2] * v : va[i];
}
)";

// Per surface vertex: C = sum_k w_k (X + A)_particle(k); the mapping rows are bound as
// Neighbours (particles), Values (weights) and Lengths.
const char* const kSurface = R"(
void main() {
  int v = int(gl_GlobalInvocationID.x);
  if (v >= count) return;
  vec3r sum = vec3r(0);
  int base = v * stride;
  for (int k = 0; k < lengths[v]; ++k) {
    int p = neighbours[base + k];
    sum += shape_values[base + k] * (vec3r(rest[3 * p], rest[3 * p + 1], rest[3 * p + 2]) + LOADA(p));
  }
  vc[3 * v] = sum.x;
  vc[3 * v + 1] = sum.y;
  vc[3 * v + 2] = sum.z;
}
)";


// Per element: the rotation R_e maximising tr(R^T F_e), F_e = sum_n x_n (x) grad phi_n the
// MLS deformation gradient (EfgRotation::deformation_gradient), by rotation_extraction.hpp's
// extract_rotation: Newton steps omega = (tr(N) I - sym N)^-1 g on the axis-angle of
// N = F R^T (g its axial vector), a scaled gradient step where that matrix is not positive
// definite, warm-started with the last quaternion (orientations, x y z w). F is formed as
// G0 + H (as in element_stress) so that float keeps its digits. Writes W = R - I from the
// quaternion directly (-2 (y^2 + z^2) etc.: no 1 - 1 in float). An element that has not
// settled after 24 steps (the CPU then takes the SVD polar) sets flags[0]; the host then
// takes this step's rotations from the CPU instead.
const char* const kElementRotation = R"(
// sin and cos of angle / 2. GLSL has them for float only: in double, a Taylor series for the
// small angles of the last Newton steps (error below 1e-16 for angle < 1), float trig for
// larger ones, whose error the next steps remove.
void half_angle_sine_cosine(real angle, out real s, out real c) {
  real x = angle * real(0.5);
#ifdef DOUBLE_PRECISION
  if (x < 0.5lf) {
    real x2 = x * x;
    s = x * (1.0lf - x2 / 6.0lf * (1.0lf - x2 / 20.0lf * (1.0lf - x2 / 42.0lf * (1.0lf - x2 / 72.0lf *
        (1.0lf - x2 / 110.0lf * (1.0lf - x2 / 156.0lf * (1.0lf - x2 / 210.0lf)))))));
    c = 1.0lf - x2 / 2.0lf * (1.0lf - x2 / 12.0lf * (1.0lf - x2 / 30.0lf * (1.0lf - x2 / 56.0lf *
        (1.0lf - x2 / 90.0lf * (1.0lf - x2 / 132.0lf * (1.0lf - x2 / 182.0lf * (1.0lf - x2 / 240.0lf)))))));
    return;
  }
  s = real(sin(float(x)));
  c = real(cos(float(x)));
#else
  s = sin(x);
  c = cos(x);
#endif
}

void main() {
  int e = int(gl_GlobalInvocationID.x);
  if (e >= count) return;
  int base = e * stride;
  int row_length = lengths[e];
  int first = neighbours[base];
  vec3r reference = LOADA(first);
  mat3r h = mat3r(0);
  for (int k = 0; k < row_length; ++k) h += outerProduct(LOADA(neighbours[base + k]) - reference, GRADIENT(base + k));
  mat3r rest_gradient;
  LOAD_MATRIX(rest_gradient, rest_gradients, e);
  mat3r f = rest_gradient + h;
  real x = orientations[4 * e], y = orientations[4 * e + 1], z = orientations[4 * e + 2], w = orientations[4 * e + 3];
  bool settled = false;
  bool finite_f = finite3(f[0]) && finite3(f[1]) && finite3(f[2]);
  if (!finite_f) settled = true;
  for (int iteration = 0; iteration < 24 && !settled; ++iteration) {
    mat3r rotation;  // column-major: rotation[c][r] = R(r, c)
    rotation[0][0] = real(1) - real(2) * (y * y + z * z);
    rotation[1][0] = real(2) * (x * y - z * w);
    rotation[2][0] = real(2) * (x * z + y * w);
    rotation[0][1] = real(2) * (x * y + z * w);
    rotation[1][1] = real(1) - real(2) * (x * x + z * z);
    rotation[2][1] = real(2) * (y * z - x * w);
    rotation[0][2] = real(2) * (x * z - y * w);
    rotation[1][2] = real(2) * (y * z + x * w);
    rotation[2][2] = real(1) - real(2) * (x * x + y * y);
    mat3r n = f * transpose(rotation);
    vec3r g = vec3r(n[1][2] - n[2][1], n[2][0] - n[0][2], n[0][1] - n[1][0]);  // N(2,1)-N(1,2), ...
    real trace = n[0][0] + n[1][1] + n[2][2];
    mat3r hessian = trace * mat3r(1) - real(0.5) * (n + transpose(n));
    // Positive definite (Sylvester) -> Newton step, else the scaled gradient step.
    real a = hessian[0][0], b = hessian[1][0], d = hessian[1][1];
    real minor2 = a * d - b * b;
    real det = determinant(hessian);
    vec3r omega;
    if (a > real(0) && minor2 > real(0) && det > real(0)) omega = inverse(hessian) * g;
    else omega = g / (abs(trace) + TINY);
    real angle = length(omega);
    if (!(angle > real(0))) {
      settled = true;  // N is symmetric: R is the polar rotation already
      break;
    }
    vec3r axis = omega / angle;
    real s, cw;
    half_angle_sine_cosine(angle, s, cw);
    real ax = axis.x * s, ay = axis.y * s, az = axis.z * s;
    // (ax, ay, az, cw) * (x, y, z, w), Hamilton product, then normalised.
    real nx = cw * x + ax * w + ay * z - az * y;
    real ny = cw * y - ax * z + ay * w + az * x;
    real nz = cw * z + ax * y - ay * x + az * w;
    real nw = cw * w - ax * x - ay * y - az * z;
    real norm = sqrt(nx * nx + ny * ny + nz * nz + nw * nw);
    x = nx / norm; y = ny / norm; z = nz / norm; w = nw / norm;
    if (angle < SETTLED_ANGLE) settled = true;
  }
  if (!settled) flags[0] = 1;
  orientations[4 * e] = x;
  orientations[4 * e + 1] = y;
  orientations[4 * e + 2] = z;
  orientations[4 * e + 3] = w;
  real offsets[9] = real[9](-real(2) * (y * y + z * z), real(2) * (x * y - z * w), real(2) * (x * z + y * w),
                            real(2) * (x * y + z * w), -real(2) * (x * x + z * z), real(2) * (y * z - x * w),
                            real(2) * (x * z - y * w), real(2) * (y * z + x * w), -real(2) * (x * x + y * y));
  for (int i = 0; i < 9; ++i) rotation_offsets[9 * e + i] = offsets[i];
}
)";

}  // namespace

const char* kernel_name(Kernel kernel) {
  switch (kernel) {
    case Kernel::element_stress: return "element_stress";
    case Kernel::node_gather: return "node_gather";
    case Kernel::diagonal: return "diagonal";
    case Kernel::right_hand_side: return "right_hand_side";
    case Kernel::scale_guess: return "scale_guess";
    case Kernel::residual_init: return "residual_init";
    case Kernel::dot_partial: return "dot_partial";
    case Kernel::dot_final: return "dot_final";
    case Kernel::cg_update: return "cg_update";
    case Kernel::cg_direction: return "cg_direction";
    case Kernel::cg_check: return "cg_check";
    case Kernel::integrate: return "integrate";
    case Kernel::surface: return "surface";
    case Kernel::integration_points: return "integration_points";
    case Kernel::element_rotation: return "element_rotation";
    case Kernel::count: break;
  }
  return "?";
}

std::string kernel_source(Kernel kernel, bool double_precision) {
  std::string source = "#version 450\n";
  if (double_precision) {
    // GLSL literals are float unless suffixed: the kernels write real(0.5) etc., which is
    // exact for the constants used, so no float-rounded constant enters double code.
    source += "#extension GL_ARB_gpu_shader_fp64 : require\n#define DOUBLE_PRECISION 1\n#define real double\n#define vec3r dvec3\n#define mat3r dmat3\n";
  } else {
    source += "#define real float\n#define vec3r vec3\n#define mat3r mat3\n";
  }
  // The Newton steps are quadratic: a step below this leaves an error of its square.
  source += double_precision ? "#define SETTLED_ANGLE 1e-8lf\n#define TINY 1e-9lf\n"
                              : "#define SETTLED_ANGLE 3e-5\n#define TINY 1e-9\n";
  source += "#define REDUCE_THREADS " + std::to_string(kReduceGroups * kGroupSize) + "\n";
  const int group = kernel == Kernel::dot_final || kernel == Kernel::cg_check ? 1 : kGroupSize;
  source += "layout(local_size_x = " + std::to_string(group) + ") in;\n";
  std::string body;
  switch (kernel) {
    case Kernel::element_stress: body = kElementStress; break;
    case Kernel::node_gather: body = kNodeGather; break;
    case Kernel::diagonal: body = kDiagonal; break;
    case Kernel::right_hand_side: body = kRightHandSide; break;
    case Kernel::scale_guess: body = kScaleGuess; break;
    case Kernel::residual_init: body = kResidualInit; break;
    case Kernel::dot_partial: body = kDotPartial; break;
    case Kernel::dot_final: body = kDotFinal; break;
    case Kernel::cg_update: body = kCgUpdate; break;
    case Kernel::cg_direction: body = kCgDirection; break;
    case Kernel::cg_check: body = kCgCheck; break;
    case Kernel::integrate: body = kIntegrate; break;
    // Integration points use the same gather with the element rows and phi bound.
    case Kernel::surface:
    case Kernel::integration_points: body = kSurface; break;
    case Kernel::element_rotation: body = kElementRotation; break;
    case Kernel::count: break;
  }
  // The common part with only the blocks the body names (directly or through LOADA, LOADB,
  // GRADIENT).
  std::string expanded = body;
  if (body.find("LOADA(") != std::string::npos) expanded += " va ";
  if (body.find("LOADB(") != std::string::npos) expanded += " vb ";
  if (body.find("GRADIENT(") != std::string::npos) expanded += " gradients ";
  if (body.find("CG_DONE") != std::string::npos) expanded += " flags ";
  const auto names = [&expanded](const std::string& name) {
    const auto word = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; };
    for (size_t at = expanded.find(name); at != std::string::npos; at = expanded.find(name, at + 1)) {
      const bool starts = at == 0 || !word(expanded[at - 1]);
      const bool ends = at + name.size() >= expanded.size() || !word(expanded[at + name.size()]);
      if (starts && ends) return true;
    }
    return false;
  };
  const std::string common = kCommon;
  size_t line_start = 0;
  while (line_start < common.size()) {
    size_t line_end = common.find('\n', line_start);
    if (line_end == std::string::npos) line_end = common.size();
    const std::string line = common.substr(line_start, line_end - line_start);
    line_start = line_end + 1;
    const size_t open = line.find("{ ");
    if (line.rfind("layout(std430", 0) == 0 && open != std::string::npos) {
      // "... { real name[]; };": the array's name.
      const size_t name_start = line.find(' ', open + 2) + 1;
      const std::string name = line.substr(name_start, line.find('[', name_start) - name_start);
      if (!names(name)) continue;
    }
    source += line + "\n";
  }
  source += body;
  return source;
}

}  // namespace incise::physics::gpu
