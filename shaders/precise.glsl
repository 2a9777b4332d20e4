// PRECISE: the qualifier on every piece of arithmetic whose order the CPU
// mirror (src/trace/) repeats. The exact kernels (render.spv, probe.spv)
// keep it `precise`, so that a driver may neither reorder nor fuse it and
// lavapipe matches the mirror bit for bit. build.rs compiles render.comp a
// second time with WHITTED_FAST_MATH defined (render_fast.spv, `--gpu-math
// fast`): PRECISE is then empty and the driver may reorder and contract
// (fuse) the arithmetic as it likes. Every file that writes PRECISE
// includes this one first.
#ifndef WHITTED_PRECISE_GLSL
#define WHITTED_PRECISE_GLSL

#ifdef WHITTED_FAST_MATH
#define PRECISE
#else
#define PRECISE precise
#endif

#endif
