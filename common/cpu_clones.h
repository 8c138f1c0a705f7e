#pragma once
// HNNSTEREO_TARGET_CLONES("avx2", "default"): x86-64 function multiversioning - the compiler
// builds the function once per listed target and the loader picks the best one the CPU has.
// GCC only (Clang's target_clones differs), and not under ThreadSanitizer: the clone resolver
// (an ifunc) runs while the loader relocates the program, before TSan's runtime exists, and
// its instrumented entry crashed every TSan binary at start. Elsewhere it expands to nothing.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_THREAD__)
#define HNNSTEREO_TARGET_CLONES(...) __attribute__((target_clones(__VA_ARGS__)))
#else
#define HNNSTEREO_TARGET_CLONES(...)
#endif
