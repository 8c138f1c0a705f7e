// Streaming read bandwidth of the OpenCL device: the roofline of a solve that streams its
// weights (perf/device_bandwidth.h, `bench`'s device_read_gbps). Every work-item sums its share
// of a float array with four independent float4 accumulators and writes one partial sum, so the
// loads are the only traffic that grows with the array (STREAM's habit, read-only).
//
// stream_read_strided: work-item g reads float4 number g, g + G, g + 2G, ... (G = global size):
//   neighbouring work-items read neighbouring addresses - coalesced loads on a GPU.
// stream_read_chunked: work-item g reads one contiguous chunk of `chunk` float16s - on a CPU
//   device, where one work-item runs on one core and streams its own pages with 16-wide loads.

__kernel void stream_read_strided(__global const float4* data, const uint n4,
                                  __global float* partial) {
  const uint g = get_global_id(0);
  const uint G = get_global_size(0);
  float4 a = (float4)(0.0f), b = (float4)(0.0f), c = (float4)(0.0f), d = (float4)(0.0f);
  uint i = g;
  for (; i + 3 * G < n4; i += 4 * G) {
    a += data[i];
    b += data[i + G];
    c += data[i + 2 * G];
    d += data[i + 3 * G];
  }
  for (; i < n4; i += G) a += data[i];
  const float4 s = (a + b) + (c + d);
  partial[g] = (s.x + s.y) + (s.z + s.w);
}

__kernel void stream_read_chunked(__global const float16* data, const uint chunk,
                                  __global float* partial) {
  const uint g = get_global_id(0);
  __global const float16* p = data + (size_t)g * chunk;
  float16 a = (float16)(0.0f), b = (float16)(0.0f);
  uint i = 0;
  for (; i + 1 < chunk; i += 2) {
    a += p[i];
    b += p[i + 1];
  }
  if (i < chunk) a += p[i];
  const float16 s = a + b;
  const float8 h8 = s.lo + s.hi;
  const float4 h4 = h8.lo + h8.hi;
  partial[g] = (h4.x + h4.y) + (h4.z + h4.w);
}
