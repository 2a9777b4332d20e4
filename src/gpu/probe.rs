//! Probe kernels (`shaders/probe.comp`): one shader function run on many
//! inputs, so tests can hold each GLSL function against its Rust twin.

use bytemuck::{Pod, Zeroable};

/// One probe input (binding 9). For most modes: ray origin `o.xyz`,
/// direction `d.xyz`, tmax `o.w`; see `ProbeMode` for the rest.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ProbeItem {
    pub o: [f32; 4],
    pub d: [f32; 4],
    pub u: [u32; 4],
}

/// One probe output (binding 10).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ProbeResult {
    pub a: [f32; 4],
    pub b: [f32; 4],
    pub u: [u32; 4],
}

/// What `probe.comp` runs on each item (push constant `probe.x`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum ProbeMode {
    /// `intersect(prims[u.x])`: a = (hit, t, u, v), b.xyz = geometric
    /// normal, result u.xyz = bits of the shading normal.
    Intersect = 0,
    /// `closest_hit`: a = (hit, t, u, v), u.x = primitive (0xFFFFFFFF: none).
    Closest = 1,
    /// `transmittance` over distance o.w: a.xyz.
    Transmittance = 2,
    /// `refract_dir(i = d.xyz, n = o.xyz, eta = o.w)`: a = (ok, dir),
    /// b.xyz = `reflect_dir(i, n)`.
    Refract = 3,
    /// `trace_ray` from o along d: a.xyz colour, u = (eye_hit, reflect,
    /// refract, shadow).
    Trace = 4,
    /// a.xyz = `eye_dir(g, o.x, o.y)`, a.w = `rand01(u.x, u.y, u.z)`,
    /// u.x = `hash(u.x)`, u.y, u.z = bits of `sample_pos(g, u.x, u.y, u.z)`.
    Sample = 5,
    /// `solve_quadratic(o.x, o.y, o.z)`: a = (ok, t0, t1, 0).
    Solve = 6,
}

/// Items per workgroup of `probe.comp`.
pub const PROBE_LOCAL_SIZE: u32 = 64;
