// Continuous Hopfield network for stereo matching (thesis ch. 6), OpenCL C 1.2.
// The kernels imitate the parallel analog chip the thesis proposed: every neuron evolves at once
// (explicit Euler steps of the Hopfield-Tank equation du/dt = -u/tau + sum_b W_ab V_b + I_a).
// CPU reference: host/hopfield_energy.cc, host/hopfield_network.cc, host/cpu_engines.cc.
//
// Build options (-D): OBJECTIVE (0 thesis eq. 6.6-6.8, 1 printed0, 2 printed1, 3 printed2,
// 4 geometry x similarity), COMPAT_TYPE (0 sigmoid eq. 6.6, 1 exponential),
// DISTANCE_ATTENUATION (0/1), DISCRETE (0 continuous, 1 discrete activation).
//
// Connection layout (host/hopfield_network.h): neuron a of left feature i is connected to the
// neurons of every left feature j in feature_neighbours(i); its weights are stored contiguously
// from weight_offsets[a] in (j, b) order, with a zero in its own slot. Many independent networks
// are concatenated (block diagonal), so the same kernels solve a batch.

#ifndef OBJECTIVE
#define OBJECTIVE 0
#endif
#ifndef COMPAT_TYPE
#define COMPAT_TYPE 0
#endif
#ifndef DISTANCE_ATTENUATION
#define DISTANCE_ATTENUATION 0
#endif
#ifndef DISCRETE
#define DISCRETE 0
#endif

#define MAX_DISPARITY_GRADIENT 1e6f
#define MIN_COMPAT_DENOMINATOR 1e-3f

typedef struct {
  float A, B, C, D;
  float W1, W2, T, lambda;
  float theta, weight_offset, attenuation_centre, attenuation_slope;
} EnergyParams;

// ch. 5.3.5: |d_a - d_b| / |c_a - c_b|, d = right - left (2D), c = (left + right) / 2.
// Written on scalar components: PoCL's loop vectoriser cannot widen float2 values, and the flat
// weight-building kernel relies on it.
float disparity_gradient_xy(float lax, float lay, float rax, float ray,
                            float lbx, float lby, float rbx, float rby) {
  const float ddx = (rax - lax) - (rbx - lbx);
  const float ddy = (ray - lay) - (rby - lby);
  const float change = sqrt(ddx * ddx + ddy * ddy);
  const float csx = 0.5f * (lax + rax) - 0.5f * (lbx + rbx);
  const float csy = 0.5f * (lay + ray) - 0.5f * (lby + rby);
  const float separation = sqrt(csx * csx + csy * csy);
  const float gradient = fmin(change / separation, MAX_DISPARITY_GRADIENT);
  return separation < 1e-9f ? (change < 1e-9f ? 0.0f : MAX_DISPARITY_GRADIENT) : gradient;
}

float disparity_gradient(float2 la, float2 ra, float2 lb, float2 rb) {
  return disparity_gradient_xy(la.x, la.y, ra.x, ra.y, lb.x, lb.y, rb.x, rb.y);
}

// f(X): eq. 6.6 (sigmoid) or the printed type 1 (exponential); X = +inf gives -1.
float compatibility_function(float X, const EnergyParams p) {
  if (isinf(X)) return X > 0.0f ? -1.0f : 1.0f;
#if COMPAT_TYPE == 1
  return 2.0f * exp(-X / p.T) - 1.0f;
#else
  const float z = p.lambda * (X - p.theta);
  if (z > 80.0f) return -1.0f;
  return 2.0f / (1.0f + native_exp(z)) - 1.0f;
#endif
}

float compatibility_xy(float lax, float lay, float rax, float ray, float ma,
                       float lbx, float lby, float rbx, float rby, float mb, const EnergyParams p) {
#if OBJECTIVE == 0
  const float g = 2.0f * native_exp(-disparity_gradient_xy(lax, lay, rax, ray, lbx, lby, rbx, rby) / p.T) - 1.0f;  // eq. 6.8
  const float s = p.W1 * g + p.W2 * (ma + mb);                                   // eq. 6.7
  return compatibility_function(s < MIN_COMPAT_DENOMINATOR ? INFINITY : 1.0f / s, p);
#elif OBJECTIVE == 1
  const float disparity_change =
      fabs(sqrt((rax - lax) * (rax - lax) + (ray - lay) * (ray - lay)) -
           sqrt((rbx - lbx) * (rbx - lbx) + (rby - lby) * (rby - lby)));
  const float separation_change =
      fabs(sqrt((lax - lbx) * (lax - lbx) + (lay - lby) * (lay - lby)) -
           sqrt((rax - rbx) * (rax - rbx) + (ray - rby) * (ray - rby)));
  return compatibility_function(0.4f * disparity_change + 0.6f * separation_change, p);
#elif OBJECTIVE == 2
  return disparity_gradient_xy(lax, lay, rax, ray, lbx, lby, rbx, rby);
#elif OBJECTIVE == 3
  return (ma + mb + 2.0f) / 4.0f;
#else
  const float g = 2.0f * native_exp(-disparity_gradient_xy(lax, lay, rax, ray, lbx, lby, rbx, rby) / p.T) - 1.0f;
  return g * (ma + 1.0f) * (mb + 1.0f) / 4.0f;
#endif
}

float compatibility(float2 la, float2 ra, float ma, float2 lb, float2 rb, float mb,
                    const EnergyParams p) {
  return compatibility_xy(la.x, la.y, ra.x, ra.y, ma, lb.x, lb.y, rb.x, rb.y, mb, p);
}

// Weight construction, one work-item per neuron: 2 A C_ab (+ offset) (eq. 6.11 without the
// uniqueness terms, which come from row and column sums), optional distance attenuation.
__kernel void build_weights(const int n_neurons,
                            __global const float2* left_point,       // per neuron
                            __global const float2* right_point,      // per neuron
                            __global const float* correlation,       // per neuron
                            __global const int* neuron_row,
                            __global const float2* feature_point,    // per left feature
                            __global const int* row_offsets,
                            __global const int* feature_neighbour_offsets,
                            __global const int* feature_neighbours,
                            __global const long* weight_offsets,
                            const EnergyParams p,
                            __global float* weights) {
  const int a = get_global_id(0);
  if (a >= n_neurons) return;
  const int i = neuron_row[a];
  const float2 la = left_point[a];
  const float2 ra = right_point[a];
  const float ma = correlation[a];
  long position = weight_offsets[a];
  for (int t = feature_neighbour_offsets[i]; t < feature_neighbour_offsets[i + 1]; ++t) {
    const int j = feature_neighbours[t];
    const int first = row_offsets[j];
    const int last = row_offsets[j + 1];
#if DISTANCE_ATTENUATION
    const float2 dl = feature_point[i] - feature_point[j];
    const float attenuation =
        1.0f / (1.0f + exp(p.attenuation_slope * (length(dl) - p.attenuation_centre)));
#endif
    for (int b = first; b < last; ++b, ++position) {
      float w = 0.0f;
      if (b != a) {
        w = 2.0f * p.A * compatibility(la, ra, ma, left_point[b], right_point[b], correlation[b], p) +
            p.weight_offset;
#if DISTANCE_ATTENUATION
        w *= attenuation;
#endif
      }
      weights[position] = w;
    }
  }
}

// Row sums (one work-item per left feature) and column sums (one per column) of V.
__kernel void line_sums(const int n_rows, const int n_columns,
                        __global const int* row_offsets,
                        __global const int* column_offsets,
                        __global const int* column_neurons,
                        __global const float* V,
                        __global float* row_sums,
                        __global float* column_sums) {
  const int g = get_global_id(0);
  if (g < n_rows) {
    float sum = 0.0f;
    for (int a = row_offsets[g]; a < row_offsets[g + 1]; ++a) sum += V[a];
    row_sums[g] = sum;
  } else if (g < n_rows + n_columns) {
    const int k = g - n_rows;
    float sum = 0.0f;
    for (int t = column_offsets[k]; t < column_offsets[k + 1]; ++t) sum += V[column_neurons[t]];
    column_sums[k] = sum;
  }
}

// e^x lane by lane, written out in fma, rint and integer ops: e^x = 2^n e^r with n = rint(x / ln 2)
// and r = x - n ln 2 (ln 2 in two parts), e^r by Cephes' expf polynomial (S. L. Moshier, Cephes
// Math Library: relative error about 1e-7 on |r| <= ln 2 / 2). x is clamped to [-87, 87], where
// 2^n stays a normal float (e^x is then 1.6e-38 or 6.1e37). The same bits in every vector width
// and as a scalar, which PoCL's exp is not (its scalar and vector exp differ in the last bit).
#define DEFINE_EXP_LANES(T, IT)                                                      \
  T exp_lanes_##T(const T x) {                                                     \
    const T y = clamp(x, -87.0f, 87.0f);                                           \
    const T n = rint(y * 1.44269504088896341f);                                    \
    const T r = fma(n, (T)(2.12194440e-4f), fma(n, (T)(-0.693359375f), y));        \
    T p = fma((T)(1.9875691500e-4f), r, (T)(1.3981999507e-3f));                   \
    p = fma(p, r, (T)(8.3334519073e-3f));                                          \
    p = fma(p, r, (T)(4.1665795894e-2f));                                          \
    p = fma(p, r, (T)(1.6666665459e-1f));                                          \
    p = fma(p, r, (T)(5.0000001201e-1f));                                          \
    return (fma(p, r * r, r) + 1.0f) * as_##T((convert_##IT(n) + 127) << 23);      \
  }
DEFINE_EXP_LANES(float, int)
DEFINE_EXP_LANES(float4, int4)
DEFINE_EXP_LANES(float8, int8)
DEFINE_EXP_LANES(float16, int16)

// The continuous activation V = (1 + tanh(u / alpha)) / 2 (the thesis's), computed as the same
// function's other form, the logistic 1 / (1 + e^(-2u / alpha)), with exp_lanes: the same bits
// whether a row is finished alone (float4), in fours (float16) or as a wider row (float8), in
// fewer instructions than PoCL's tanh. V below 2^-25 is 0, as (1 + tanh) / 2 rounds it in float (tanh(x) is -1 for
// x < -9.01): a neuron that far OFF stays exactly 0, which the on-the-fly step skips.
#define DEFINE_ACTIVATION(T)                                        \
  T activation_##T(const T u, const float alpha) {                  \
    const T v = 1.0f / (1.0f + exp_lanes_##T(u * (-2.0f / alpha))); \
    return select(v, (T)(0.0f), v < 0x1.0p-25f);                    \
  }
DEFINE_ACTIVATION(float)
DEFINE_ACTIVATION(float4)
DEFINE_ACTIVATION(float8)
DEFINE_ACTIVATION(float16)

float activate(float u, float alpha, float previous) {
#if DISCRETE
  return u > 0.0f ? 1.0f : (u < 0.0f ? 0.0f : previous);
#else
  return activation_float(u, alpha);
#endif
}

// The net input of every neuron at state V: field_a = sum_b W_ab V_b + I_a, and the energy term
// e_a = -V_a (1/2 sum_b W_ab V_b + I_a), so that E = sum_a e_a (eq. 6.10).
__kernel void neuron_field(const int n_neurons,
                           __global const int* neuron_row,
                           __global const int* neuron_column,
                           __global const int* row_offsets,
                           __global const int* feature_neighbour_offsets,
                           __global const int* feature_neighbours,
                           __global const long* weight_offsets,
                           __global const float* weights,
                           __global const float* bias,
                           __global const float* row_sums,
                           __global const float* column_sums,
                           const float two_B, const float two_C,
                           __global const int* network_of_neuron,
                           __global const int* active,
                           __global const float* V,
                           __global float* field,
                           __global float* energy_terms) {
  const int a = get_global_id(0);
  if (a >= n_neurons) return;
  // A frozen (converged) network keeps its state, field and energy terms: skip its neurons.
  if (!active[network_of_neuron[a]]) return;
  const int i = neuron_row[a];
  const float va = V[a];
  long position = weight_offsets[a];
  float sum = 0.0f;
  for (int t = feature_neighbour_offsets[i]; t < feature_neighbour_offsets[i + 1]; ++t) {
    const int j = feature_neighbours[t];
    for (int b = row_offsets[j]; b < row_offsets[j + 1]; ++b, ++position) {
      sum += weights[position] * V[b];
    }
  }
  // Uniqueness (eq. 6.11): -2B over the rest of the row, -2C over the rest of the column.
  sum -= two_B * (row_sums[i] - va);
  sum -= two_C * (column_sums[neuron_column[a]] - va);
  const float ia = bias[a];
  field[a] = sum + ia;
  energy_terms[a] = -va * (0.5f * sum + ia);
}

// One lockstep explicit Euler step of the Hopfield-Tank equation for every neuron of an active
// network: u += dt (-u / tau + field), V = g(u). Frozen (converged) networks keep their state.
__kernel void neuron_euler(const int n_neurons,
                           __global const int* network_of_neuron,
                           __global const int* active,
                           const float dt, const float inv_tau, const float alpha,
                           __global const float* field,
                           __global float* u,
                           __global float* V) {
  const int a = get_global_id(0);
  if (a >= n_neurons) return;
  if (!active[network_of_neuron[a]]) return;
  const float ua = u[a] + dt * (-u[a] * inv_tau + field[a]);
  u[a] = ua;
  V[a] = activate(ua, alpha, V[a]);
}

// Per-network sums of the energy terms: one work-group per network, a uniform tree reduction
// in local memory (local size must be a power of two, at most 256).
__kernel void segment_sum(__global const int* segment_offsets,
                          __global const float* values,
                          __global float* sums,
                          __local float* scratch) {
  const int segment = get_group_id(0);
  const int lid = get_local_id(0);
  const int size = get_local_size(0);
  float sum = 0.0f;
  for (int a = segment_offsets[segment] + lid; a < segment_offsets[segment + 1]; a += size) {
    sum += values[a];
  }
  scratch[lid] = sum;
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int stride = size / 2; stride > 0; stride /= 2) {
    if (lid < stride) scratch[lid] += scratch[lid + stride];
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  if (lid == 0) sums[segment] = scratch[0];
}

// ---------------------------------------------------------------------------------------------
// Row-blocked engine (host/device_network_blocks.cc): the same network and the same Euler steps, laid
// out for streaming. Every row (left feature) is padded to ROW_PAD neuron slots (slot i*ROW_PAD
// + k; padded slots hold V = 0 and are never written), and the weights between row i and its
// neighbour row j are one dense ROW_PAD x ROW_PAD block, stored contiguously in the order of
// feature_neighbours(i). One work-item handles a run of whole rows and does, in one launch per
// step: the compatibility input sum_b W_ab V_b (blocks read with vector loads; or computed on
// the fly from per-slot data), the row sum, the uniqueness terms, the energy terms and the
// Euler step (double-buffered V, so the update stays a Jacobi step as on the analog chip).
//
// Build options: ROW_PAD (multiple of 4), WEIGHTS (0 float blocks, 1 half blocks - vload_half,
// core OpenCL 1.2 - with float accumulation, 2 on the fly: no stored weights at all),
// BLOCK_COLS (the neighbour slots q a block stores: ROW_PAD, or 3 when ROW_PAD is 4 and no row
// has a fourth neuron - hnn-default's K = 3 - so a block is 3 x 4 instead of 4 x 4: a quarter
// fewer bytes to stream, the same sums, since a padded slot's V is 0).
#ifndef ROW_PAD
#define ROW_PAD 4
#endif
#ifndef BLOCK_COLS
#define BLOCK_COLS ROW_PAD
#endif
#if BLOCK_COLS != ROW_PAD && !(BLOCK_COLS == 3 && ROW_PAD == 4)
#error "BLOCK_COLS is ROW_PAD, or 3 with ROW_PAD 4"
#endif
#define BLOCK_SIZE (BLOCK_COLS * ROW_PAD)
#ifndef WEIGHTS
#define WEIGHTS 0
#endif
#define ROW_CHUNKS (ROW_PAD / 4)

// The weight between slot (i, k) and slot (j, q), exactly as build_weights computes it.
float slot_weight(const int i, const int k, const int j, const int q,
                  __global const float2* slot_right, __global const float* slot_correlation,
                  __global const float2* feature_point, const EnergyParams p) {
  if (i == j && k == q) return 0.0f;
  const float2 la = feature_point[i];
  const float2 lb = feature_point[j];
  float w = 2.0f * p.A * compatibility(la, slot_right[i * ROW_PAD + k],
                                       slot_correlation[i * ROW_PAD + k], lb,
                                       slot_right[j * ROW_PAD + q],
                                       slot_correlation[j * ROW_PAD + q], p) +
            p.weight_offset;
#if DISTANCE_ATTENUATION
  const float2 dl = la - lb;
  w *= 1.0f / (1.0f + exp(p.attenuation_slope * (length(dl) - p.attenuation_centre)));
#endif
  return w;
}

// Column sums over padded slots (feature-vs-feature networks only): one work-item per column.
// Column k's sum of V over its slots (column_sums_blocked, solve_blocked_resident).
float column_sum(const int k, __global const int* column_offsets,
                 __global const int* column_slots, __global const float* V) {
  float sum = 0.0f;
  for (int t = column_offsets[k]; t < column_offsets[k + 1]; ++t) sum += V[column_slots[t]];
  return sum;
}

__kernel void column_sums_blocked(const int n_columns,
                                  __global const int* column_offsets,
                                  __global const int* column_slots,
                                  __global const float* V,
                                  __global float* column_sums) {
  const int k = get_global_id(0);
  if (k >= n_columns) return;
  column_sums[k] = column_sum(k, column_offsets, column_slots, V);
}

// finish_row's parameters (one signature for its three variants below).
#define FINISH_ROW_PARAMS                                                                    \
  const int i, const int ni, const float* acc, __global const float* slot_bias,              \
      __global const int* slot_column, __global const float* column_sums, const float two_B, \
      const float two_C, const float dt, const float inv_tau, const float alpha,             \
      __global const float* V_in, __global const float* u_in, __global float* V_out,         \
      __global float* u_out, __global float* row_energy
#if ROW_PAD == 4
// The live slots of the four 4-slot rows i .. i + 3 as one int16 mask (lane 4r + k: slot k of
// row i + r exists), for the four-row finish and decisions.
int16 live_slots_of_rows4(__global const int* row_count, const int i) {
  return (int16)(0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3) <
         vload4(0, row_count + i).s0000111122223333;
}
#endif

// The rest of row i's Euler step once `acc` holds its compatibility input sum_b W_ab V_b: the
// row and column uniqueness terms (eq. 6.11), the bias, the row's energy term at V_in (eq. 6.10)
// and the step of u and V into the other state buffer.
#if ROW_PAD == 4 && !DISCRETE
// 4-slot rows (hnn-default's top-4 network): the four slots as one float4, so that the activation
// - the costliest part of a step on a CPU device once the blocks sit in cache - is one vector
// call. Padded slots (k >= ni) are masked to 0 and never written; the sums run in the scalar
// loop's order.
void finish_row(FINISH_ROW_PARAMS) {
  const int base = i * 4;
  const int4 live = (int4)(0, 1, 2, 3) < (int4)(ni);
  const float4 zero = (float4)(0.0f);
  const float4 va = select(zero, vload4(i, V_in), live);
  const float row_sum = ((va.x + va.y) + va.z) + va.w;
  float4 sum = vload4(0, acc) - two_B * (row_sum - va);
  if (two_C != 0.0f) {
    float4 cs = zero;
    if (ni > 0) cs.x = column_sums[slot_column[base]];
    if (ni > 1) cs.y = column_sums[slot_column[base + 1]];
    if (ni > 2) cs.z = column_sums[slot_column[base + 2]];
    if (ni > 3) cs.w = column_sums[slot_column[base + 3]];
    sum -= two_C * (cs - va);
  }
  const float4 ia = select(zero, vload4(i, slot_bias), live);
  const float4 e = va * (0.5f * sum + ia);
  row_energy[i] = -(((e.x + e.y) + e.z) + e.w);
  const float4 ua = select(zero, vload4(i, u_in), live);
  const float4 next = ua + dt * (-ua * inv_tau + sum + ia);
  const float4 v = activation_float4(next, alpha);
  if (ni == 4) {
    vstore4(next, i, u_out);
    vstore4(v, i, V_out);
  } else {
    if (ni > 0) { u_out[base] = next.x; V_out[base] = v.x; }
    if (ni > 1) { u_out[base + 1] = next.y; V_out[base + 1] = v.y; }
    if (ni > 2) { u_out[base + 2] = next.z; V_out[base + 2] = v.z; }
  }
}

// Rows i .. i + 3 finished together: the float4 finish_row's arithmetic lane by lane on one
// float16, so that the activation is one 16-wide call instead of four 4-wide ones (on a CPU
// device the finish is a chain of dependent vector operations, longer than the block loop once
// the blocks sit in cache). Padded slots keep their values (V 0), as finish_row leaves them.
__attribute__((always_inline)) void finish_rows4(const int i, const float16 acc,
                                                __global const int* row_count,
                  __global const float* slot_bias, __global const int* slot_column,
                  __global const float* column_sums, const float two_B, const float two_C,
                  const float dt, const float inv_tau, const float alpha,
                  __global const float* V_in, __global const float* u_in, __global float* V_out,
                  __global float* u_out, __global float* row_energy) {
  const int base = i * 4;
  const int16 live = live_slots_of_rows4(row_count, i);
  const float16 zero = (float16)(0.0f);
  const float16 v_raw = vload16(0, V_in + base);
  const float16 va = select(zero, v_raw, live);
  // Each row's ((V0 + V1) + V2) + V3 as four 4-wide adds of the rows' slots k = 0..3 (swizzles,
  // not sixteen scalar extracts: the same sums); the energies below the same way.
  const float4 row_sum = ((va.s048c + va.s159d) + va.s26ae) + va.s37bf;
  float16 sum = acc - two_B * (row_sum.s0000111122223333 - va);
  if (two_C != 0.0f) {
    float cs[16];
    for (int l = 0; l < 16; ++l) {
      cs[l] = l % 4 < row_count[i + l / 4] ? column_sums[slot_column[base + l]] : 0.0f;
    }
    sum -= two_C * (vload16(0, cs) - va);
  }
  const float16 ia = select(zero, vload16(0, slot_bias + base), live);
  const float16 e = va * (0.5f * sum + ia);
  vstore4(-(((e.s048c + e.s159d) + e.s26ae) + e.s37bf), 0, row_energy + i);
  const float16 u_raw = vload16(0, u_in + base);
  const float16 ua = select(zero, u_raw, live);
  const float16 next = ua + dt * (-ua * inv_tau + sum + ia);
  const float16 v = activation_float16(next, alpha);
  vstore16(select(u_raw, next, live), 0, u_out + base);
  vstore16(select(v_raw, v, live), 0, V_out + base);
}
#elif !DISCRETE
// Wider rows (8, 12, ... slots: the pick cell's feature network) in chunks of FINISH_W slots
// (8 where the row pad allows, else 4), each as one vector: one vector activation per chunk
// instead of a scalar one per slot. The energy terms are added in slot order, as the scalar loop
// adds them.
#if ROW_PAD % 8 == 0
#define FINISH_W 8
#define activationW activation_float8
#define floatW float8
#define intW int8
#define vloadW vload8
#define vstoreW vstore8
#define FINISH_LANES (int8)(0, 1, 2, 3, 4, 5, 6, 7)
#else
#define FINISH_W 4
#define activationW activation_float4
#define floatW float4
#define intW int4
#define vloadW vload4
#define vstoreW vstore4
#define FINISH_LANES (int4)(0, 1, 2, 3)
#endif
void finish_row(FINISH_ROW_PARAMS) {
  const int base = i * ROW_PAD;
  float row_sum = 0.0f;
  for (int k = 0; k < ni; ++k) row_sum += V_in[base + k];
  const floatW zero = (floatW)(0.0f);
  float energy = 0.0f;
  for (int c = 0; c < ROW_PAD / FINISH_W && FINISH_W * c < ni; ++c) {
    const int k0 = base + FINISH_W * c;
    const int live_slots = min(FINISH_W, ni - FINISH_W * c);
    const intW live = FINISH_LANES < (intW)(live_slots);
    const floatW va = select(zero, vloadW(0, V_in + k0), live);
    floatW sum = vloadW(c, acc) - two_B * (row_sum - va);
    if (two_C != 0.0f) {
      float cs[FINISH_W];
      for (int l = 0; l < FINISH_W; ++l)
        cs[l] = l < live_slots ? column_sums[slot_column[k0 + l]] : 0.0f;
      sum -= two_C * (vloadW(0, cs) - va);
    }
    const floatW ia = select(zero, vloadW(0, slot_bias + k0), live);
    float e[FINISH_W];
    vstoreW(va * (0.5f * sum + ia), 0, e);
    for (int l = 0; l < FINISH_W; ++l) energy -= e[l];
    const floatW ua = select(zero, vloadW(0, u_in + k0), live);
    const floatW next = ua + dt * (-ua * inv_tau + sum + ia);
    const floatW v = activationW(next, alpha);
    if (live_slots == FINISH_W) {
      vstoreW(next, 0, u_out + k0);
      vstoreW(v, 0, V_out + k0);
    } else {
      float next_slots[FINISH_W], v_slots[FINISH_W];
      vstoreW(next, 0, next_slots);
      vstoreW(v, 0, v_slots);
      for (int l = 0; l < live_slots; ++l) {
        u_out[k0 + l] = next_slots[l];
        V_out[k0 + l] = v_slots[l];
      }
    }
  }
  row_energy[i] = energy;
}
#else
void finish_row(FINISH_ROW_PARAMS) {
  const int base = i * ROW_PAD;
  float row_sum = 0.0f;
  for (int k = 0; k < ni; ++k) row_sum += V_in[base + k];
  float energy = 0.0f;
  for (int k = 0; k < ni; ++k) {
    const float va = V_in[base + k];
    float sum = acc[k] - two_B * (row_sum - va);
    if (two_C != 0.0f) sum -= two_C * (column_sums[slot_column[base + k]] - va);
    const float ia = slot_bias[base + k];
    energy -= va * (0.5f * sum + ia);
    const float ua = u_in[base + k];
    const float next = ua + dt * (-ua * inv_tau + sum + ia);
    u_out[base + k] = next;
    V_out[base + k] = activate(next, alpha, va);
  }
  row_energy[i] = energy;
}
#endif

// Block t of a row times V of its neighbour row j, added to acc (slots k of the row): the same
// arithmetic as the per-item step's inner loop (column q of the block times V[j,q]). The
// blocks are loaded (BLOCKn) and stored (STORE_BLOCKn, the vectorised build) in their storage
// type: half blocks convert to and from float here.
#if WEIGHTS == 1
#define BLOCK4(offset) vload_half4(0, blocks + (offset))
#define BLOCK8(offset) vload_half8(0, blocks + (offset))
#define BLOCK16(n) vload_half16((n), blocks)
#define STORE_BLOCK4(v, offset) vstore_half4((v), 0, blocks + (offset))
#define STORE_BLOCK8(v, offset) vstore_half8((v), 0, blocks + (offset))
#define STORE_BLOCK16(v, n) vstore_half16((v), (n), blocks)
#define BLOCK_TYPE half
#else
#define BLOCK4(offset) vload4(0, blocks + (offset))
#define BLOCK8(offset) vload8(0, blocks + (offset))
#define BLOCK16(n) vload16((n), blocks)
#define STORE_BLOCK4(v, offset) vstore4((v), 0, blocks + (offset))
#define STORE_BLOCK8(v, offset) vstore8((v), 0, blocks + (offset))
#define STORE_BLOCK16(v, n) vstore16((v), (n), blocks)
#define BLOCK_TYPE float
#endif

// The arguments of both fused step kernels (the host sets them once for either).
#define STEP_NETWORK_PARAMS                                                                   \
  const int n_rows, const int rows_per_item, __global const int* row_count,                   \
      __global const int* feature_neighbour_offsets, __global const int* feature_neighbours,  \
      __global const BLOCK_TYPE* blocks, __global const float2* slot_right,                   \
      __global const float* slot_correlation, __global const float2* feature_point,           \
      const EnergyParams p, __global const float* slot_bias, __global const int* slot_column, \
      __global const float* column_sums, const float two_B, const float two_C,                \
      __global const int* network_of_row, __global const int* active, const float dt,         \
      const float inv_tau, const float alpha
// `check` != 0: the step also makes the kDecisions check at u_in (decide_row below) into
// `decisions` and `changes`.
#define STEP_BLOCKED_PARAMS                                                            \
  STEP_NETWORK_PARAMS, __global const float* V_in, __global const float* u_in,         \
      __global float* V_out, __global float* u_out, __global float* row_energy,        \
      __global int* decisions, __global int* changes, const int check
// Their names, to pass them on.
#define STEP_NETWORK_ARGS                                                                         \
  n_rows, rows_per_item, row_count, feature_neighbour_offsets, feature_neighbours, blocks,        \
      slot_right, slot_correlation, feature_point, p, slot_bias, slot_column, column_sums, two_B, \
      two_C, network_of_row, active, dt, inv_tau, alpha
#define STEP_BLOCKED_ARGS \
  STEP_NETWORK_ARGS, V_in, u_in, V_out, u_out, row_energy, decisions, changes, check

// The kDecisions check of row i at u (its slots from u + first), for row_decisions (CSR) and
// the row blocks' fused steps: the row's decision - the index of its neuron with the largest u
// when that u > 0, else -1 - against the previous check's, a changed row counted in
// changes[network]. The fused steps call it for every row they update at a check step, on the
// u they have just read, which saves the row blocks a launch of row_decisions a check.
void decide_row(const int i, const int ni, __global const float* u, const int first,
                __global int* decisions, __global int* changes, const int network) {
  int best = -1;
  float best_u = 0.0f;
  for (int k = 0; k < ni; ++k) {
    const float uk = u[first + k];
    if (best < 0 || uk > best_u) {
      best = k;
      best_u = uk;
    }
  }
  const int decision = best >= 0 && best_u > 0.0f ? best : -1;
  if (decision != decisions[i]) atomic_inc(&changes[network]);
  decisions[i] = decision;
}

#if ROW_PAD == 4
// decide_row for the four 4-slot rows i .. i + 3 at once, on one float16 of their u: a
// tournament of pairs then halves, where a strict > keeps the lower slot on a tie, gives each
// row's first slot of largest u, as decide_row's scan does (padded slots are -inf: never
// chosen), without decide_row's scalar scans.
void decide_rows4(const int i, __global const int* row_count, __global const float* u,
                  __global int* decisions, __global int* changes,
                  __global const int* network_of_row) {
  const int16 live = live_slots_of_rows4(row_count, i);
  const float16 ua = select((float16)(-INFINITY), vload16(0, u + i * 4), live);
  // Slots (0, 1) and (2, 3) of every row.
  const float8 even = ua.s02468ace, odd = ua.s13579bdf;
  const int8 take_odd = isgreater(odd, even);
  const float8 pair_u = select(even, odd, take_odd);
  const int8 pair_k = (int8)(0, 2, 0, 2, 0, 2, 0, 2) + (take_odd & (int8)(1));
  const int4 take_hi = isgreater(pair_u.s1357, pair_u.s0246);
  const float4 best_u = select(pair_u.s0246, pair_u.s1357, take_hi);
  const int4 best = select(pair_k.s0246, pair_k.s1357, take_hi);
  const int4 decision = select((int4)(-1), best, isgreater(best_u, (float4)(0.0f)));
  const int4 changed = decision != vload4(0, decisions + i);
  if (changed.x) atomic_inc(&changes[network_of_row[i]]);
  if (changed.y) atomic_inc(&changes[network_of_row[i + 1]]);
  if (changed.z) atomic_inc(&changes[network_of_row[i + 2]]);
  if (changed.w) atomic_inc(&changes[network_of_row[i + 3]]);
  vstore4(decision, 0, decisions + i);
}
#endif

// Row i's compatibility input acc[k] = sum over its neighbour blocks t in [first, end) (every
// stride-th) of block t times V of the neighbour row, k < ROW_PAD. Both step kernels call it: the
// per-item one with the row's whole range, the group one with a lane's share.
//
// The stored blocks are added into two independent accumulator chains (even and odd blocks of
// the range, or the halves of an 8-slot block), summed once after the loop: one chain makes
// every block wait for the previous block's FMA (about the time of the block's loads), two let
// consecutive blocks overlap.
void row_input(const int i, const int ni, const int first, const int end, const int stride,
               __global const int* row_count, __global const int* feature_neighbours,
               __global const BLOCK_TYPE* blocks, __global const float2* slot_right,
               __global const float* slot_correlation, __global const float2* feature_point,
               const EnergyParams p, __global const float* V_in, float* acc) {
#if WEIGHTS == 2
  for (int k = 0; k < ROW_PAD; ++k) acc[k] = 0.0f;
  for (int t = first; t < end; t += stride) {
    const int j = feature_neighbours[t];
    const int nj = row_count[j];
    for (int q = 0; q < nj; ++q) {
      const float vb = V_in[j * ROW_PAD + q];
      if (vb == 0.0f) continue;
      for (int k = 0; k < ni; ++k) {
        acc[k] += slot_weight(i, k, j, q, slot_right, slot_correlation, feature_point, p) * vb;
      }
    }
  }
#elif ROW_PAD == 4 && BLOCK_COLS == 3
  // A 3 x 4 block: columns q = 0, 1 as one 8-wide vector, column 2 as a 4-wide one. (The
  // chains are named variables: PoCL keeps private arrays in memory.)
  float8 acc8_0 = (float8)(0.0f), acc8_1 = (float8)(0.0f);
  float4 acc_q2_0 = (float4)(0.0f), acc_q2_1 = (float4)(0.0f);
  int t = first;
  for (; t + stride < end; t += 2 * stride) {
    const float4 v0 = vload4(feature_neighbours[t], V_in);
    const float4 v1 = vload4(feature_neighbours[t + stride], V_in);
    const size_t b0 = (size_t)t * BLOCK_SIZE;
    const size_t b1 = (size_t)(t + stride) * BLOCK_SIZE;
    acc8_0 += BLOCK8(b0) * v0.s00001111;
    acc_q2_0 += BLOCK4(b0 + 8) * v0.s2222;
    acc8_1 += BLOCK8(b1) * v1.s00001111;
    acc_q2_1 += BLOCK4(b1 + 8) * v1.s2222;
  }
  if (t < end) {
    const float4 vj = vload4(feature_neighbours[t], V_in);
    const size_t block = (size_t)t * BLOCK_SIZE;
    acc8_0 += BLOCK8(block) * vj.s00001111;
    acc_q2_0 += BLOCK4(block + 8) * vj.s2222;
  }
  const float8 sum8 = acc8_0 + acc8_1;
  // (q0 + q1) + (q2 + q3) as the 4 x 4 sum adds them, with q3 = 0 there: the same bits.
  vstore4((sum8.lo + sum8.hi) + (acc_q2_0 + acc_q2_1), 0, acc);
#elif ROW_PAD == 4
  // The whole 4 x 4 block as one 16-wide vector (one AVX-512 register on a CPU device):
  // column q times V[j,q] with V[j] spread to (V0 x4, V1 x4, V2 x4, V3 x4); the four
  // columns are summed once after the loop. One conversion and one FMA a block.
  float16 acc16_0 = (float16)(0.0f), acc16_1 = (float16)(0.0f);
  int t = first;
  for (; t + stride < end; t += 2 * stride) {
    acc16_0 += BLOCK16(t) * vload4(feature_neighbours[t], V_in).s0000111122223333;
    acc16_1 += BLOCK16(t + stride) *
               vload4(feature_neighbours[t + stride], V_in).s0000111122223333;
  }
  if (t < end) acc16_0 += BLOCK16(t) * vload4(feature_neighbours[t], V_in).s0000111122223333;
  const float16 sum16 = acc16_0 + acc16_1;
  vstore4((sum16.s0123 + sum16.s4567) + (sum16.s89ab + sum16.scdef), 0, acc);
#elif ROW_PAD == 8
  // Two 8-slot columns a 16-wide vector (column q at q * 8, slots k fastest), each times its
  // V[j,q]; columns 0-3 and 4-7 in the two chains, the halves summed once after the loop.
  float16 acc16_0 = (float16)(0.0f), acc16_1 = (float16)(0.0f);
  for (int t = first; t < end; t += stride) {
    const float8 vj = vload8(feature_neighbours[t], V_in);
    acc16_0 += BLOCK16(4 * t) * vj.s0000000011111111;
    acc16_0 += BLOCK16(4 * t + 1) * vj.s2222222233333333;
    acc16_1 += BLOCK16(4 * t + 2) * vj.s4444444455555555;
    acc16_1 += BLOCK16(4 * t + 3) * vj.s6666666677777777;
  }
  const float16 sum16 = acc16_0 + acc16_1;
  vstore8(sum16.lo + sum16.hi, 0, acc);
#else
  // acc += block * V[j]: column q of the (column-major) block times V[j,q], four slots k a
  // vector FMA, no horizontal sums.
  float4 acc4[ROW_CHUNKS];
  for (int c = 0; c < ROW_CHUNKS; ++c) acc4[c] = (float4)(0.0f);
  for (int t = first; t < end; t += stride) {
    const int j = feature_neighbours[t];
    const size_t block = (size_t)t * BLOCK_SIZE;
    for (int q = 0; q < BLOCK_COLS; ++q) {
      const float vq = V_in[j * ROW_PAD + q];
      for (int c = 0; c < ROW_CHUNKS; ++c) {
        acc4[c] += BLOCK4(block + q * ROW_PAD + 4 * c) * vq;
      }
    }
  }
  for (int c = 0; c < ROW_CHUNKS; ++c) vstore4(acc4[c], c, acc);
#endif
}

// Rows [first, last) of one fused Euler step (the two kernels below that run rows on one
// work-item): reads V_in and u_in, writes V_out, u_out and the energy term of every row at V_in
// (E = sum of row_energy, eq. 6.10).
void step_rows(const int first, const int last, STEP_BLOCKED_PARAMS) {
  int i = first;
#if ROW_PAD == 4 && !DISCRETE
  // Four rows at a time, finished as one float16, where all four belong to active networks.
  for (; i + 4 <= last; i += 4) {
    // A network's rows are consecutive: where the first and the last of the four share a
    // network, all four do.
    const int network = network_of_row[i];
    if (network == network_of_row[i + 3] ? active[network]
                                         : active[network] && active[network_of_row[i + 1]] &&
                                               active[network_of_row[i + 2]] &&
                                               active[network_of_row[i + 3]]) {
      // Each row's input in its own array, read back as the 4-wide vector it was stored as: one
      // 16-wide read of four 4-wide stores cannot be forwarded from the stores and waits for them.
      float acc0[4], acc1[4], acc2[4], acc3[4];
      row_input(i, row_count[i], feature_neighbour_offsets[i], feature_neighbour_offsets[i + 1], 1,
                row_count, feature_neighbours, blocks, slot_right, slot_correlation, feature_point,
                p, V_in, acc0);
      row_input(i + 1, row_count[i + 1], feature_neighbour_offsets[i + 1],
                feature_neighbour_offsets[i + 2], 1, row_count, feature_neighbours, blocks,
                slot_right, slot_correlation, feature_point, p, V_in, acc1);
      row_input(i + 2, row_count[i + 2], feature_neighbour_offsets[i + 2],
                feature_neighbour_offsets[i + 3], 1, row_count, feature_neighbours, blocks,
                slot_right, slot_correlation, feature_point, p, V_in, acc2);
      row_input(i + 3, row_count[i + 3], feature_neighbour_offsets[i + 3],
                feature_neighbour_offsets[i + 4], 1, row_count, feature_neighbours, blocks,
                slot_right, slot_correlation, feature_point, p, V_in, acc3);
      const float16 acc = (float16)(vload4(0, acc0), vload4(0, acc1), vload4(0, acc2),
                                    vload4(0, acc3));
      finish_rows4(i, acc, row_count, slot_bias, slot_column, column_sums, two_B, two_C, dt,
                   inv_tau, alpha, V_in, u_in, V_out, u_out, row_energy);
      if (check) decide_rows4(i, row_count, u_in, decisions, changes, network_of_row);
      continue;
    }
    for (int r = i; r < i + 4; ++r) {
      if (!active[network_of_row[r]]) continue;
      float acc[ROW_PAD];
      row_input(r, row_count[r], feature_neighbour_offsets[r], feature_neighbour_offsets[r + 1], 1,
                row_count, feature_neighbours, blocks, slot_right, slot_correlation, feature_point,
                p, V_in, acc);
      finish_row(r, row_count[r], acc, slot_bias, slot_column, column_sums, two_B, two_C, dt,
                 inv_tau, alpha, V_in, u_in, V_out, u_out, row_energy);
      if (check) {
        decide_row(r, row_count[r], u_in, r * ROW_PAD, decisions, changes, network_of_row[r]);
      }
    }
  }
#endif
  for (; i < last; ++i) {
    const int ni = row_count[i];
    // A frozen (converged) network is not touched: the state buffer it stopped on keeps V_s.
    if (!active[network_of_row[i]]) continue;
    float acc[ROW_PAD];
    row_input(i, ni, feature_neighbour_offsets[i], feature_neighbour_offsets[i + 1], 1, row_count,
              feature_neighbours, blocks, slot_right, slot_correlation, feature_point, p, V_in, acc);
    finish_row(i, ni, acc, slot_bias, slot_column, column_sums, two_B, two_C, dt, inv_tau, alpha,
               V_in, u_in, V_out, u_out, row_energy);
    if (check) decide_row(i, ni, u_in, i * ROW_PAD, decisions, changes, network_of_row[i]);
  }
}

// One fused Euler step for rows [item * rows_per_item, +rows_per_item).
__kernel void neuron_step_blocked(STEP_BLOCKED_PARAMS) {
  const int first = get_global_id(0) * rows_per_item;
  step_rows(first, min(n_rows, first + rows_per_item), STEP_BLOCKED_ARGS);
}

// The whole blocked solve in one launch (OpenClEngineOptions::SolveLoop::kDevice: networks on a
// CPU device). It runs BlockedNetwork::SolveOnHost itself - the fused step of every row as
// neuron_step_blocked does it, and at every `interval`-th step (and at max_steps) the energy and
// the stop rule (host/device_network.cc, CheckConvergence; kDecisions counted by the step's
// decide_row) - so the solve costs one launch and one read instead of a launch per step and a
// host round trip per check, which on a CPU device cost about as much as a step whose blocks
// sit in the cores' caches.
// One network (no batch). State buffers 0 and 1 as the host loop's parities; `decisions` starts
// at -2. With column uniqueness (n_column_ranges > 0) every step first sums the columns of V_in
// (column_sums_blocked's sums, in ranges of columns claimed as the rows' are), then steps the
// rows; control[0] then counts these phases, two a step.
//
// The rows are cut into n_ranges ranges (range_rows: cuts at multiples of four rows, about equal
// work). Work-groups of one work-item each (a thread each on a CPU device) take the ranges of the
// current step by claiming them: claims[r] holds the last step range r was taken for, and
// atomic_cmpxchg(claims[r], step - 1, step) lets exactly one group take it. Each group tries its
// own share of the ranges first (so a range stays in one core's cache from step to step), then
// the others'. The group that finishes a step's last range does the step's bookkeeping - at a
// check the energy (the row energies in row order), the decision changes and the stop rule -
// and moves control[0] to the next step (or to -1: stop); the others wait for that. So each step
// is one Jacobi step of the whole network, whoever computes a range computes it the same way,
// and the result is bit for bit that of one group. No group waits for another to arrive: a
// group whose thread is taken off its core holds up a step only while it holds a range, and the
// others take its ranges meanwhile (a barrier would stall every group behind a descheduled
// one). Groups that never run at once (PoCL with one
// thread) do no harm: a group that starts after the stop finds control[0] = -1.
// control = (step or phase, ranges finished in it, stable checks, checks), all 0 at the start;
// claims and column_claims start at -1 (as the host makes the buffers: one launch a network).
// `result` is all the host reads back, in one read: the outcome (steps, converged,
// stop parity, checks; ints in float bits), then energy_trace[c] = E at check c for c <
// n_checks (E as the sum of row_energy in row order, where segment_sum adds a tree: equal up to
// float rounding), then V and u of every slot as the network stopped (n_rows * ROW_PAD each,
// copied by the group that stops it).
// solve_blocked_resident: a range of the current phase is done (its writes fenced before). Returns
// 1 for the phase's last of n ranges, after resetting the count for the next phase; the caller
// then opens the next phase (control[0]).
int last_range_of_phase(volatile __global int* control, const int n) {
  mem_fence(CLK_GLOBAL_MEM_FENCE);
  if (atomic_inc(&control[1]) != n - 1) return 0;
  control[1] = 0;
  return 1;
}

__kernel void solve_blocked_resident(STEP_NETWORK_PARAMS, __global float* V0, __global float* u0,
                                     __global float* V1, __global float* u1,
                                     __global float* row_energy, __global int* decisions,
                                     __global int* range_changes, const int max_steps,
                                     const int interval, const int stable_checks,
                                     const int by_decisions, const float energy_tolerance,
                                     const float decision_tolerance,
                                     __global float* result, const int n_checks,
                                     __global const int* range_rows, const int n_ranges,
                                     volatile __global int* claims,
                                     volatile __global int* control,
                                     __global const int* column_offsets,
                                     __global const int* column_slots,
                                     __global float* column_sums_out,
                                     __global const int* column_range_columns,
                                     const int n_column_ranges,
                                     volatile __global int* column_claims) {
  if (get_local_id(0) != 0) return;
  __global float* energy_trace = result + 4;
  const int own = (int)((long)n_ranges * get_group_id(0) / get_num_groups(0));
  // With column uniqueness a step has two phases: the column sums of V_in, then the rows.
  const int phases = n_column_ranges > 0 ? 2 : 1;
  for (;;) {
    const int tick = control[0];
    if (tick < 0) return;
    const int step = tick / phases;
    const int parity = step & 1;
    if (phases == 2 && tick % 2 == 0) {
      // The column sums of V_in (column_sums_blocked), ranges of columns claimed as the rows'.
      __global const float* V = parity ? V1 : V0;
      const int own_columns = (int)((long)n_column_ranges * get_group_id(0) / get_num_groups(0));
      for (int k = 0; k < n_column_ranges; ++k) {
        const int c = (own_columns + k) % n_column_ranges;
        if (atomic_cmpxchg(&column_claims[c], step - 1, step) != step - 1) continue;
        for (int col = column_range_columns[c]; col < column_range_columns[c + 1]; ++col) {
          column_sums_out[col] = column_sum(col, column_offsets, column_slots, V);
        }
        if (!last_range_of_phase(control, n_column_ranges)) continue;
        mem_fence(CLK_GLOBAL_MEM_FENCE);
        control[0] = tick + 1;
        break;
      }
      while (control[0] == tick) {
      }
      mem_fence(CLK_GLOBAL_MEM_FENCE);
      continue;
    }
    __global float* V_in = parity ? V1 : V0;
    __global float* u_in = parity ? u1 : u0;
    __global float* V_out = parity ? V0 : V1;
    __global float* u_out = parity ? u0 : u1;
    const int check = step % interval == 0 || step == max_steps;
    for (int k = 0; k < n_ranges; ++k) {
      const int r = (own + k) % n_ranges;
      if (atomic_cmpxchg(&claims[r], step - 1, step) != step - 1) continue;  // taken
      // The rows' decisions at u_in are made inside the step (decide_row) at a check; a single
      // network, so decide_row counts into range_changes[r + network_of_row] = range_changes[r].
      range_changes[r] = 0;
      step_rows(range_rows[r], range_rows[r + 1], STEP_NETWORK_ARGS, V_in, u_in, V_out, u_out,
                row_energy, decisions, range_changes + r, check && by_decisions);
      if (!last_range_of_phase(control, n_ranges)) continue;
      // The step's last range: its bookkeeping, then the next step.
      int next = tick + 1;
      if (check) {
        float E = 0.0f;
        for (int i = 0; i < n_rows; ++i) E += row_energy[i];
        int n_changed = 0;
        for (int h = 0; h < n_ranges; ++h) n_changed += range_changes[h];
        const int checks = control[3];
        int stable = control[2];
        if (step > 0) {
          const int settled = by_decisions ? (float)n_changed <= decision_tolerance
                                           : fabs(E - energy_trace[checks - 1]) <= energy_tolerance;
          stable = settled ? stable + 1 : 0;
        }
        energy_trace[checks] = E;
        control[2] = stable;
        control[3] = checks + 1;
        if (stable >= stable_checks || step >= max_steps) {
          result[0] = as_float(step);
          result[1] = as_float(stable >= stable_checks ? 1 : 0);
          result[2] = as_float(parity);
          result[3] = as_float(checks + 1);
          // The state the network stops on (V_in, u_in: the host loop's rule), after the trace.
          __global float* final_state = energy_trace + n_checks;
          const int n_slots = n_rows * ROW_PAD;
          for (int k = 0; k < n_slots; ++k) final_state[k] = V_in[k];
          for (int k = 0; k < n_slots; ++k) final_state[n_slots + k] = u_in[k];
          next = -1;
        }
      }
      mem_fence(CLK_GLOBAL_MEM_FENCE);
      control[0] = next;
      break;
    }
    while (control[0] == tick) {
    }
    mem_fence(CLK_GLOBAL_MEM_FENCE);
  }
}

// The same fused Euler step with one work-group of STEP_GROUP work-items per row (a GPU:
// OpenClEngineOptions::BlockStep::kRowPerGroup). The row's neighbour blocks are contiguous in t,
// so lane l taking blocks t = first + l, first + l + STEP_GROUP, ... makes neighbouring lanes
// read neighbouring blocks (coalesced loads), and a row's work is spread over STEP_GROUP lanes
// instead of one, which keeps a GPU's memory busy where a work-item per row cannot. The lanes'
// partial inputs are summed in local
// memory (`partial`: STEP_GROUP x ROW_PAD floats, passed by the host), then lane 0 finishes the
// row exactly as the per-item kernel does. Same arguments as neuron_step_blocked
// (rows_per_item is 1 here).
__kernel void neuron_step_blocked_group(STEP_BLOCKED_PARAMS, __local float* partial) {
  const int i = get_group_id(0);
  const int lane = get_local_id(0);
  const int lanes = get_local_size(0);
  // Uniform per group: a whole group leaves together, before any barrier.
  if (i >= n_rows || !active[network_of_row[i]]) return;
  const int ni = row_count[i];
  float acc[ROW_PAD];
  row_input(i, ni, feature_neighbour_offsets[i] + lane, feature_neighbour_offsets[i + 1], lanes,
            row_count, feature_neighbours, blocks, slot_right, slot_correlation, feature_point, p,
            V_in, acc);
  // Tree sum of the lanes' partial inputs (lanes is a power of two).
  for (int k = 0; k < ROW_PAD; ++k) partial[k * lanes + lane] = acc[k];
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int half_lanes = lanes / 2; half_lanes > 0; half_lanes /= 2) {
    if (lane < half_lanes) {
      for (int k = 0; k < ni; ++k) partial[k * lanes + lane] += partial[k * lanes + lane + half_lanes];
    }
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  if (lane != 0) return;
  for (int k = 0; k < ni; ++k) acc[k] = partial[k * lanes];
  finish_row(i, ni, acc, slot_bias, slot_column, column_sums, two_B, two_C, dt, inv_tau, alpha,
             V_in, u_in, V_out, u_out, row_energy);
  if (check) decide_row(i, ni, u_in, i * ROW_PAD, decisions, changes, network_of_row[i]);
}

// The kDecisions stop rule (host/hopfield_options.h): the decision of every row of an active
// network - the index within the row of its neuron with the largest u when that u > 0, else -1 -
// is compared with the previous check's; changed rows are counted per network. Rows are given
// as (first index into u, neuron count): the CSR layout (the row blocks' steps decide
// themselves).
__kernel void row_decisions(const int n_rows,
                            __global const int* row_first,
                            __global const int* row_size,
                            __global const int* network_of_row,
                            __global const int* active,
                            __global const float* u,
                            __global int* decisions,
                            __global int* changes) {
  const int i = get_global_id(0);
  if (i >= n_rows) return;
  const int network = network_of_row[i];
  if (!active[network]) return;
  decide_row(i, row_size[i], u, row_first[i], decisions, changes, network);
}

// The weight blocks, one work-item per weight: (block t, q, k) from the global id; block t of
// row i holds W[(i,k),(j,q)] at t * BLOCK_SIZE + q * ROW_PAD + k (column q of the block
// contiguous, so the step adds column q times V[j,q] with vector FMAs; padded slots get 0), and
// block_row[t] is that row i. The build of a GPU, and of every objective without the
// vectorised per-row build below.
__kernel void build_weight_blocks_flat(const long n_weights,
                                       __global const int* block_row,
                                       __global const int* feature_neighbours,
                                       __global const int* row_count,
                                       __global const float2* slot_right,
                                       __global const float* slot_correlation,
                                       __global const float2* feature_point,
                                       const EnergyParams p,
#if WEIGHTS == 1
                                       __global half* blocks
#else
                                       __global float* blocks
#endif
                                       ) {
  const long at = get_global_id(0);
  if (at >= n_weights) return;
  const int t = (int)(at / BLOCK_SIZE);
  const int qk = (int)(at - (long)t * BLOCK_SIZE);
  const int q = qk / ROW_PAD;
  const int k = qk - q * ROW_PAD;
  const int i = block_row[t];
  const int j = feature_neighbours[t];
  const float w = (k < row_count[i] && q < row_count[j])
                      ? slot_weight(i, k, j, q, slot_right, slot_correlation, feature_point, p)
                      : 0.0f;
#if WEIGHTS == 1
  vstore_half(w, at, blocks);
#else
  blocks[at] = w;
#endif
}

#if OBJECTIVE == 4 && !DISTANCE_ATTENUATION
// First index in [first, last) of the sorted list a whose value is >= value (binary search).
int lower_bound_int(__global const int* a, int first, int last, const int value) {
  while (first < last) {
    const int middle = first + (last - first) / 2;
    if (a[middle] < value) first = middle + 1; else last = middle;
  }
  return first;
}

// The weight blocks of the geometry x similarity objective (hnn-default), one work-item per row,
// written with float4 over four neighbour slots q at a time (explicit vectors: PoCL's loop
// vectoriser declines the scalar builds). Same formula as compatibility() (objective 4) and
// disparity_gradient(): w = 2 A g (M_a + 1)(M_b + 1) / 4 + offset, g = 2 exp(-DG / T) - 1.
// The weight is symmetric (DG and the product of the similarities are, eq. 6.11), so row i
// computes only its blocks with neighbours j >= i (a suffix of its sorted list) and also writes
// each one transposed into row j's block for i (found by binary search in j's sorted list):
// half the exponentials and square roots, every block written by exactly one work-item.
__kernel void build_weight_blocks_vec4(const int n_rows,
                                       __global const int* row_count,
                                       __global const int* feature_neighbour_offsets,
                                       __global const int* feature_neighbours,
                                       __global const float2* slot_right,
                                       __global const float* slot_correlation,
                                       __global const float2* feature_point,
                                       const EnergyParams p,
#if WEIGHTS == 1
                                       __global half* blocks
#else
                                       __global float* blocks
#endif
                                       ) {
  const int i = get_global_id(0);
  if (i >= n_rows) return;
  const int ni = row_count[i];
  const float2 la = feature_point[i];
  const int4 lane = (int4)(0, 1, 2, 3);
  const int list_end = feature_neighbour_offsets[i + 1];
  for (int t = lower_bound_int(feature_neighbours, feature_neighbour_offsets[i], list_end, i);
       t < list_end; ++t) {
    const int j = feature_neighbours[t];
    const int nj = row_count[j];
    const float2 lb = feature_point[j];
    // Row j's block for row i (the transpose); none for the row's own block.
    const int mirror = j == i ? -1
                              : lower_bound_int(feature_neighbours, feature_neighbour_offsets[j],
                                                feature_neighbour_offsets[j + 1], i);
#if ROW_PAD == 4
    // The whole 4 x 4 block as one 16-wide vector, lane q * 4 + k (column-major): slot k of row
    // i varies fastest (.s0123 repeated), slot q of row j slowest (.s0000111122223333). The
    // mirror block is its transpose (.s048c159d26ae37bf).
    {
      const float8 ra01 = vload8(0, (__global const float*)(slot_right + i * 4));  // x0 y0 x1 y1 ..
      const float8 rb01 = vload8(0, (__global const float*)(slot_right + j * 4));
      const float4 rax = ra01.s0246, ray = ra01.s1357, rbx = rb01.s0246, rby = rb01.s1357;
      const float4 ma = vload4(i, slot_correlation), mb = vload4(j, slot_correlation);
      const float16 ax = rax.s0123012301230123, ay = ray.s0123012301230123;
      const float16 bx = rbx.s0000111122223333, by = rby.s0000111122223333;
      const float16 ddx = (ax - la.x) - (bx - lb.x);
      const float16 ddy = (ay - la.y) - (by - lb.y);
      const float16 change = sqrt(ddx * ddx + ddy * ddy);
      const float16 csx = 0.5f * (la.x + ax) - 0.5f * (lb.x + bx);
      const float16 csy = 0.5f * (la.y + ay) - 0.5f * (lb.y + by);
      const float16 separation = sqrt(csx * csx + csy * csy);
      float16 gradient = fmin(change / separation, (float16)(MAX_DISPARITY_GRADIENT));
      const float16 coincident = select((float16)(MAX_DISPARITY_GRADIENT), (float16)(0.0f),
                                        change < 1e-9f);
      gradient = select(gradient, coincident, separation < 1e-9f);
      const float16 g = 2.0f * native_exp(-gradient / p.T) - 1.0f;
      const float16 w = 2.0f * p.A * (g * (ma.s0123012301230123 + 1.0f) *
                                      (mb.s0000111122223333 + 1.0f) / 4.0f) + p.weight_offset;
      const int16 k16 = (int16)(0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3);
      const int16 q16 = (int16)(0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3);
      const int16 real = (k16 < ni) & (q16 < nj) & !((q16 == k16) & (i == j ? (int16)(-1) : (int16)(0)));
      const float16 block = select((float16)(0.0f), w, real);
#if BLOCK_COLS == 3
      // 3 x 4 blocks: the first 12 lanes (q < 3); lane q = 3 is padding (nj <= 3), and so is
      // lane k = 3 of the transpose (ni <= 3).
      const float16 mirrored = block.s048c159d26ae37bf;
      const size_t at = (size_t)t * BLOCK_SIZE, mirror_at = (size_t)mirror * BLOCK_SIZE;
      STORE_BLOCK8(block.lo, at);
      STORE_BLOCK4(block.s89ab, at + 8);
      if (mirror >= 0) {
        STORE_BLOCK8(mirrored.lo, mirror_at);
        STORE_BLOCK4(mirrored.s89ab, mirror_at + 8);
      }
#else
      STORE_BLOCK16(block, t);
      if (mirror >= 0) STORE_BLOCK16(block.s048c159d26ae37bf, mirror);
#endif
    }
#else
    for (int c = 0; c < ROW_CHUNKS; ++c) {
      const int b0 = j * ROW_PAD + 4 * c;
      const float4 rbx = (float4)(slot_right[b0].x, slot_right[b0 + 1].x, slot_right[b0 + 2].x,
                                  slot_right[b0 + 3].x);
      const float4 rby = (float4)(slot_right[b0].y, slot_right[b0 + 1].y, slot_right[b0 + 2].y,
                                  slot_right[b0 + 3].y);
      const float4 mb = vload4(0, slot_correlation + b0);
      const int4 q = lane + 4 * c;
      // Four slots k at a time, each a float4 over four slots q; both blocks are written with
      // vector stores (below).
      for (int k0 = 0; k0 < ROW_PAD; k0 += 4) {
        float4 w[4];
        for (int r = 0; r < 4; ++r) {
          const int k = k0 + r;
          const float2 ra = slot_right[i * ROW_PAD + k];
          const float ma = slot_correlation[i * ROW_PAD + k];
          const float4 ddx = (ra.x - la.x) - (rbx - lb.x);
          const float4 ddy = (ra.y - la.y) - (rby - lb.y);
          const float4 change = sqrt(ddx * ddx + ddy * ddy);
          const float4 csx = 0.5f * (la.x + ra.x) - 0.5f * (lb.x + rbx);
          const float4 csy = 0.5f * (la.y + ra.y) - 0.5f * (lb.y + rby);
          const float4 separation = sqrt(csx * csx + csy * csy);
          float4 gradient = fmin(change / separation, (float4)(MAX_DISPARITY_GRADIENT));
          const float4 coincident = select((float4)(MAX_DISPARITY_GRADIENT), (float4)(0.0f),
                                           change < 1e-9f);
          gradient = select(gradient, coincident, separation < 1e-9f);
          const float4 g = 2.0f * native_exp(-gradient / p.T) - 1.0f;
          float4 wk = 2.0f * p.A * (g * (ma + 1.0f) * (mb + 1.0f) / 4.0f) + p.weight_offset;
          // Vector comparisons give -1 (all bits) for true, which select() needs; a scalar one
          // gives 1, so the row's own bound stays a scalar test.
          const int4 real = (q < nj) & !((q == k) & (i == j ? (int4)(-1) : (int4)(0)));
          w[r] = k < ni ? select((float4)(0.0f), wk, real) : (float4)(0.0f);
        }
        // Column-major blocks: block t takes the four columns q = 4c..4c+3 (rows k0..k0+3 of
        // each, i.e. the register transpose of w); row j's block for i (the mirror) holds
        // W[(j,q),(i,k)] = W[(i,k),(j,q)] at k * ROW_PAD + q, i.e. w[r] itself at column k.
        const float4 m0 = (float4)(w[0].x, w[1].x, w[2].x, w[3].x);
        const float4 m1 = (float4)(w[0].y, w[1].y, w[2].y, w[3].y);
        const float4 m2 = (float4)(w[0].z, w[1].z, w[2].z, w[3].z);
        const float4 m3 = (float4)(w[0].w, w[1].w, w[2].w, w[3].w);
        const size_t at = ((size_t)t * ROW_PAD + 4 * c) * ROW_PAD + k0;
        STORE_BLOCK4(m0, at);
        STORE_BLOCK4(m1, at + ROW_PAD);
        STORE_BLOCK4(m2, at + 2 * ROW_PAD);
        STORE_BLOCK4(m3, at + 3 * ROW_PAD);
        if (mirror >= 0) {
          for (int r = 0; r < 4; ++r) {
            STORE_BLOCK4(w[r], ((size_t)mirror * ROW_PAD + k0 + r) * ROW_PAD + 4 * c);
          }
        }
      }
    }
#endif  // ROW_PAD == 4
  }
}
#endif
