//! Scene → other renderers' formats: NFF (the SPD's format) and POV-Ray
//! 3.7 scene language, for side-by-side timing against POV-Ray.

use crate::scene::{Material, Scene, Shape};
use anyhow::{anyhow, bail, Result};
use glam::DVec3;
use std::fmt::Write;

fn v(p: DVec3) -> String {
    format!("{} {} {}", p.x, p.y, p.z)
}

fn pv(p: DVec3) -> String {
    format!("<{}, {}, {}>", p.x, p.y, p.z)
}

/// NFF text for a scene of spheres, polygons, triangles and cones. Materials
/// map back to `f` lines (k_d from the diffuse colour's largest channel).
pub fn to_nff(s: &Scene) -> Result<String> {
    let mut o = String::new();
    let c = &s.camera;
    writeln!(o, "b {}", v(s.background))?;
    writeln!(
        o,
        "v\nfrom {}\nat {}\nup {}\nangle {}\nhither 0.001\nresolution {} {}",
        v(c.from),
        v(c.at),
        v(c.up),
        c.fov,
        c.width,
        c.height
    )?;
    for l in &s.lights {
        writeln!(o, "l {} {}", v(l.position), v(l.color))?;
    }
    let mut current = u32::MAX;
    for obj in &s.objects {
        if obj.material != current {
            current = obj.material;
            let m = &s.materials[obj.material as usize];
            let kd = m.kd.max_element();
            let col = if kd > 0.0 { m.kd / kd } else { DVec3::ONE };
            writeln!(
                o,
                "f {} {} {} {} {} {}",
                v(col),
                kd,
                m.ksr,
                m.nr,
                m.kt.max_element(),
                m.ior
            )?;
        }
        match &obj.shape {
            Shape::Sphere { center, radius } => writeln!(o, "s {} {}", v(*center), radius)?,
            Shape::Polygon { vertices } => {
                writeln!(o, "p {}", vertices.len())?;
                for p in vertices {
                    writeln!(o, "{}", v(*p))?;
                }
            }
            Shape::Triangle { vertices, normals } => match normals {
                None => writeln!(
                    o,
                    "p 3\n{}\n{}\n{}",
                    v(vertices[0]),
                    v(vertices[1]),
                    v(vertices[2])
                )?,
                Some(n) => {
                    writeln!(o, "pp 3")?;
                    for k in 0..3 {
                        writeln!(o, "{} {}", v(vertices[k]), v(n[k]))?;
                    }
                }
            },
            Shape::Cone {
                base,
                base_radius,
                apex,
                apex_radius,
            } => writeln!(
                o,
                "c {} {} {} {}",
                v(*base),
                base_radius,
                v(*apex),
                apex_radius
            )?,
            other => bail!("NFF has no {} primitive", shape_name(other)),
        }
    }
    Ok(o)
}

fn shape_name(s: &Shape) -> &'static str {
    match s {
        Shape::Sphere { .. } => "sphere",
        Shape::Plane { .. } => "plane",
        Shape::Polygon { .. } => "polygon",
        Shape::Triangle { .. } => "triangle",
        Shape::Mesh(_) => "mesh",
        Shape::Box { .. } => "box",
        Shape::Quadric { .. } => "quadric",
        Shape::Cone { .. } => "cone",
    }
}

// ---------------------------------------------------------------------------
// POV-Ray 3.7. docs/povray.md explains each mapping and what differs.

/// POV-Ray's largest `max_trace_level` (its range is 1..=256).
pub const POV_MAX_TRACE_LEVEL: u32 = 256;

/// Largest image width or height `to_pov` writes (the scene format's limit).
pub const POV_MAX_IMAGE_SIZE: u32 = 65536;

/// Pigment value given to a channel whose k_d is 0 but whose k_a is not:
/// POV-Ray's ambient is pigment × ambient, so the channel must be non-zero;
/// its diffuse share, 10⁻⁶ of the material's k_d, is invisible.
const PIGMENT_FLOOR: f64 = 1e-6;

/// Transmit of the top layer when k_t needs two texture layers (coloured,
/// or ≥ 1 on a lit surface): the bottom layer filters by k_t / this.
const LAYER_TRANSMIT: f64 = 0.5;

/// Checks `to_pov`'s arguments; returns POV-Ray's `max_trace_level`.
fn pov_args(width: u32, height: u32, max_depth: u32, min_weight: f32) -> Result<u32> {
    for (v, what) in [(width, "width"), (height, "height")] {
        if v == 0 || v > POV_MAX_IMAGE_SIZE {
            bail!("image {what} must be in 1..={POV_MAX_IMAGE_SIZE}, got {v}");
        }
    }
    // POV-Ray counts the eye ray as level 1: depth d is level d + 1.
    let level = max_depth
        .checked_add(1)
        .filter(|l| *l <= POV_MAX_TRACE_LEVEL)
        .ok_or_else(|| {
            anyhow!(
                "max depth {max_depth} does not fit POV-Ray's max_trace_level \
                 (1..={POV_MAX_TRACE_LEVEL}): use 0..={}",
                POV_MAX_TRACE_LEVEL - 1
            )
        })?;
    if !min_weight.is_finite() || !(0.0..=1.0).contains(&min_weight) {
        bail!("min weight (POV-Ray's adc_bailout) must be in [0, 1], got {min_weight}");
    }
    Ok(level)
}

/// Every number `to_pov` writes must be finite (a scene built in code may
/// hold anything; a loaded one is already checked).
fn pov_finite(s: &Scene) -> Result<()> {
    let bad = |v: &[f64]| v.iter().any(|x| !x.is_finite());
    let c = &s.camera;
    if bad(&[c.from, c.at, c.up].map(|p| p.to_array()).concat()) || !c.fov.is_finite() {
        bail!("the camera has a number that is not finite");
    }
    if bad(&s.background.to_array()) || bad(&s.ambient.to_array()) {
        bail!("the background or ambient colour is not finite");
    }
    for (i, l) in s.lights.iter().enumerate() {
        if bad(&[l.position.to_array(), l.color.to_array(), l.falloff].concat()) {
            bail!("light {i} has a number that is not finite");
        }
    }
    for (i, m) in s.materials.iter().enumerate() {
        let v = [m.ka, m.kd, m.kr, m.kt, m.absorption].map(|p| p.to_array());
        if bad(&v.concat()) || bad(&[m.ksr, m.nr, m.kst, m.nt, m.ior]) {
            bail!(
                "material {i} ({:?}) has a number that is not finite",
                m.name
            );
        }
    }
    for (i, o) in s.objects.iter().enumerate() {
        if o.material as usize >= s.materials.len() {
            bail!(
                "object {i} names material {}, which does not exist",
                o.material
            );
        }
        let ok = match &o.shape {
            Shape::Sphere { center, radius } => !bad(&center.to_array()) && radius.is_finite(),
            Shape::Plane { point, normal } => !bad(&[point.to_array(), normal.to_array()].concat()),
            Shape::Polygon { vertices } => vertices.iter().all(|p| p.is_finite()),
            Shape::Triangle { vertices, normals } => {
                vertices.iter().all(|p| p.is_finite())
                    && normals
                        .as_ref()
                        .is_none_or(|n| n.iter().all(|p| p.is_finite()))
            }
            Shape::Mesh(m) => {
                m.positions.iter().all(|p| p.is_finite())
                    && m.normals
                        .as_ref()
                        .is_none_or(|n| n.iter().all(|p| p.is_finite()))
                    && m.triangles
                        .iter()
                        .all(|t| t.iter().all(|&k| (k as usize) < m.positions.len()))
            }
            Shape::Box { min, max } => min.is_finite() && max.is_finite(),
            Shape::Quadric { coefficients, clip } => {
                !bad(coefficients) && clip.is_none_or(|(a, b)| a.is_finite() && b.is_finite())
            }
            Shape::Cone {
                base,
                base_radius,
                apex,
                apex_radius,
            } => {
                base.is_finite()
                    && apex.is_finite()
                    && base_radius.is_finite()
                    && apex_radius.is_finite()
            }
        };
        if !ok {
            bail!(
                "object {i} ({}) has a number that is not finite or an index out of range",
                shape_name(&o.shape)
            );
        }
    }
    Ok(())
}

/// Bounds of a finite shape (none for planes and unclipped quadrics).
fn shape_bounds(shape: &Shape) -> Option<(DVec3, DVec3)> {
    let of = |ps: &mut dyn Iterator<Item = DVec3>| {
        ps.fold(None, |acc: Option<(DVec3, DVec3)>, p| {
            Some(acc.map_or((p, p), |(lo, hi)| (lo.min(p), hi.max(p))))
        })
    };
    match shape {
        Shape::Sphere { center, radius } => Some((*center - *radius, *center + *radius)),
        Shape::Plane { .. } | Shape::Quadric { clip: None, .. } => None,
        Shape::Polygon { vertices } => of(&mut vertices.iter().copied()),
        Shape::Triangle { vertices, .. } => of(&mut vertices.iter().copied()),
        Shape::Mesh(m) => of(&mut m.positions.iter().copied()),
        Shape::Box { min, max } => Some((*min, *max)),
        Shape::Quadric {
            clip: Some((lo, hi)),
            ..
        } => Some((*lo, *hi)),
        Shape::Cone {
            base,
            base_radius,
            apex,
            apex_radius,
        } => {
            let r = base_radius.abs().max(apex_radius.abs());
            Some((base.min(*apex) - r, base.max(*apex) + r))
        }
    }
}

/// The box every light's fall-off is fitted over: the finite objects (or,
/// with none, a cube around the point the camera looks at).
fn scene_box(s: &Scene) -> (DVec3, DVec3) {
    let bounds = s.objects.iter().filter_map(|o| shape_bounds(&o.shape));
    bounds
        .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
        .unwrap_or_else(|| {
            let r = s.camera.from.distance(s.camera.at);
            (s.camera.at - r, s.camera.at + r)
        })
}

/// POV-Ray 3.7's light fade, s · 2 / (1 + (d / distance)^power); `power`
/// or `distance` 0 means no fade (3.7 ignores a fade without a distance).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Fade {
    scale: f64,
    distance: f64,
    power: f64,
}

/// `fade_distance`, relative to the nearest distance lit, that makes
/// 2 / (1 + (d/fd)^p) a power law 2 (fd/d)^p to 10⁻⁶ or better.
const POWER_LAW_DISTANCE: f64 = 1e-6;

impl Fade {
    fn at(&self, d: f64) -> f64 {
        if self.power == 0.0 || self.distance == 0.0 {
            self.scale
        } else {
            self.scale * 2.0 / (1.0 + (d / self.distance).powf(self.power))
        }
    }

    /// k · d^−power over distances from `near` on.
    fn power_law(k: f64, power: f64, near: f64) -> Fade {
        let distance = near * POWER_LAW_DISTANCE;
        Fade {
            scale: k / (2.0 * distance.powf(power)),
            distance,
            power,
        }
    }
}

/// Our fall-off f(d) = min(1, 1/(c1 + c2 d + c3 d²)) (1 where the
/// denominator is 0).
fn falloff_at(c: [f64; 3], d: f64) -> f64 {
    let den = c[0] + c[1] * d + c[2] * d * d;
    if den <= 1.0 {
        1.0
    } else {
        1.0 / den
    }
}

/// The POV-Ray fade closest to our fall-off `c` over distances
/// `lo..=hi`, and its largest relative error there. Exact (error 0, or
/// 10⁻⁶ for a power law) with no linear or no quadratic term where the
/// min(1, ·) clamp is inactive;
/// otherwise the fade minimising the largest error over 64 distances
/// (a grid over power and distance, the scale solved in closed form).
fn pov_fade(c: [f64; 3], lo: f64, hi: f64) -> (Fade, f64) {
    let [c1, c2, c3] = c;
    let samples: Vec<f64> = (0..64)
        .map(|i| lo * (hi / lo).powf(i as f64 / 63.0))
        .collect();
    let error = |f: &Fade| {
        samples
            .iter()
            .map(|&d| (f.at(d) / falloff_at(c, d) - 1.0).abs())
            .fold(0.0, f64::max)
    };
    let unclamped = c1 + c2 * lo + c3 * lo * lo >= 1.0;
    let exact = if c2 == 0.0 && c3 == 0.0 {
        Some(Fade {
            scale: falloff_at(c, 1.0),
            distance: 0.0,
            power: 0.0,
        })
    } else if unclamped && (c2 == 0.0 || c3 == 0.0) {
        let (k, power) = if c3 == 0.0 { (c2, 1.0) } else { (c3, 2.0) };
        Some(if c1 == 0.0 {
            Fade::power_law(1.0 / k, power, lo)
        } else {
            Fade {
                scale: 0.5 / c1,
                distance: (c1 / k).powf(1.0 / power),
                power,
            }
        })
    } else {
        None
    };
    if let Some(f) = exact {
        return (f, error(&f));
    }
    let mut best = (
        Fade {
            scale: 1.0,
            distance: 0.0,
            power: 0.0,
        },
        f64::INFINITY,
    );
    for pi in 1..=120 {
        let power = pi as f64 * 0.05;
        for di in 0..=80 {
            // A pure power law, then distances lo/100 .. hi·100.
            let unit = if di == 0 {
                Fade::power_law(1.0, power, lo)
            } else {
                Fade {
                    scale: 1.0,
                    distance: lo / 100.0 * (hi * 100.0 / (lo / 100.0)).powf((di - 1) as f64 / 79.0),
                    power,
                }
            };
            let (mut emin, mut emax) = (f64::INFINITY, f64::NEG_INFINITY);
            for &d in &samples {
                let e = unit.at(d).ln() - falloff_at(c, d).ln();
                emin = emin.min(e);
                emax = emax.max(e);
            }
            let f = Fade {
                scale: unit.scale * (-(emin + emax) / 2.0).exp(),
                ..unit
            };
            let err = error(&f);
            if err < best.1 {
                best = (f, err);
            }
        }
    }
    best
}

/// One POV-Ray texture layer.
struct Layer {
    pigment: DVec3,
    filter: f64,
    transmit: f64,
    ambient: DVec3,
    diffuse: f64,
    phong: f64,
    phong_size: f64,
    reflection: DVec3,
}

impl Layer {
    fn write(&self, o: &mut String) -> std::fmt::Result {
        write!(
            o,
            "texture {{ pigment {{ rgbft <{}, {}, {}, {}, {}> }} finish {{ ambient rgb {} diffuse {}",
            self.pigment.x,
            self.pigment.y,
            self.pigment.z,
            self.filter,
            self.transmit,
            pv(self.ambient),
            self.diffuse
        )?;
        if self.phong > 0.0 {
            write!(o, " phong {} phong_size {}", self.phong, self.phong_size)?;
        }
        if self.reflection.max_element() > 0.0 {
            write!(o, " reflection {{ rgb {} }}", pv(self.reflection))?;
        }
        write!(o, " }} }}")
    }
}

/// `#declare M<i> = material { ... }` for one material, with comments for
/// what POV-Ray cannot express.
///
/// POV-Ray 3.7 (source/backend/render/trace.cpp, ComputeLightedTexture)
/// shades a layer with pigment P, filter f, transmit t as
/// ambient·P·I_a·α + Σ diffuse·P·(N·L)·I·α + Σ phong·(R·L)^size·I, plus
/// reflection·I_R, plus (P·f + t)·I_T, with α = 1 − f − t; a second layer
/// under the first adds its own terms times the first's P·f + t and
/// filters I_T again. So with k_t grey and < 1 one layer, transmit k_t and
/// P·α = k_d reproduce k_a, k_d, k_sr, k_r and k_t exactly; otherwise the
/// top layer transmits 0.5 and a bottom layer filters by 2·k_t.
fn pov_material(o: &mut String, i: usize, m: &Material) -> std::fmt::Result {
    writeln!(
        o,
        "// material {i} {:?}: ka {} kd {} ksr {} nr {} kst {} nt {} kr {} kt {} ior {} absorption {}",
        m.name,
        pv(m.ka),
        pv(m.kd),
        m.ksr,
        m.nr,
        m.kst,
        m.nt,
        pv(m.kr),
        pv(m.kt),
        m.ior,
        pv(m.absorption)
    )?;
    if m.kst > 0.0 {
        writeln!(
            o,
            "// kst {} (V.T_L)^{}: POV-Ray has no transmission highlight; left out",
            m.kst, m.nt
        )?;
    }
    let kt = m.kt;
    let lit = m.kd.max_element() > 0.0 || m.ka.max_element() > 0.0;
    let grey = kt.x == kt.y && kt.y == kt.z;
    let (transmit, bottom) = if kt.max_element() <= 0.0 {
        (0.0, None)
    } else if grey && (kt.x < 1.0 || !lit) {
        (kt.x, None)
    } else {
        (LAYER_TRANSMIT, Some(kt / LAYER_TRANSMIT))
    };
    // α = 1 − f − t (POV-Ray 3.7's opacity); 0 only for an unlit surface.
    let alpha = (1.0 - transmit).max(0.0);
    let kd_max = m.kd.max_element();
    let ka_max = m.ka.max_element();
    let (pigment, diffuse) = if alpha == 0.0 {
        (DVec3::ZERO, 0.0)
    } else if kd_max > 0.0 {
        let p = DVec3::select(
            m.kd.cmpeq(DVec3::ZERO) & m.ka.cmpgt(DVec3::ZERO),
            DVec3::splat(PIGMENT_FLOOR),
            m.kd / kd_max,
        );
        (p, kd_max / alpha)
    } else if ka_max > 0.0 {
        ((m.ka / ka_max).max(DVec3::splat(PIGMENT_FLOOR)), 0.0)
    } else {
        (DVec3::ZERO, 0.0)
    };
    let ambient = DVec3::select(
        m.ka.cmpgt(DVec3::ZERO) & pigment.cmpgt(DVec3::ZERO),
        m.ka / (pigment * alpha),
        DVec3::ZERO,
    );
    let top = Layer {
        pigment,
        filter: 0.0,
        transmit,
        ambient,
        diffuse,
        phong: m.ksr,
        phong_size: m.nr,
        reflection: m.kr,
    };
    write!(o, "#declare M{i} = material {{ ")?;
    if let Some(b) = bottom {
        // Layers are listed bottom first.
        Layer {
            pigment: b,
            filter: 1.0,
            transmit: 0.0,
            ambient: DVec3::ZERO,
            diffuse: 0.0,
            phong: 0.0,
            phong_size: 1.0,
            reflection: DVec3::ZERO,
        }
        .write(o)?;
        write!(o, " ")?;
    }
    top.write(o)?;
    if kt.max_element() > 0.0 {
        write!(o, " interior {{ ior {}", m.ior)?;
        let sigma = m.absorption.max_element();
        if sigma > 0.0 {
            // fade_power ≥ 1000: exp(−(1 − fade_color)·d/fade_distance),
            // which is exp(−σ d) with these two.
            write!(
                o,
                " fade_distance {} fade_power 1001 fade_color rgb {}",
                1.0 / sigma,
                pv(DVec3::ONE - m.absorption / sigma)
            )?;
        }
        write!(o, " }}")?;
    }
    writeln!(o, " }}")
}

/// POV-Ray 3.7 scene text reproducing our image as closely as POV-Ray's
/// shading allows (docs/povray.md): the same camera (vertical field of
/// view, right-handed), lights and fall-off, materials and primitives;
/// `max_depth` generations of secondary rays (POV-Ray counts the eye ray as
/// level 1, so `max_trace_level` is `max_depth + 1`) and `min_weight` as
/// `adc_bailout`. Errors: a width or height outside 1..=65536, a depth past
/// 255, a min weight outside [0, 1], a number in the scene that is not
/// finite.
pub fn to_pov(
    s: &Scene,
    width: u32,
    height: u32,
    max_depth: u32,
    min_weight: f32,
) -> Result<String> {
    let level = pov_args(width, height, max_depth, min_weight)?;
    pov_finite(s)?;
    let mut o = String::new();
    let c = &s.camera;
    let aspect = width as f64 / height as f64;
    // POV-Ray's `angle` is the horizontal field of view.
    let hfov = 2.0 * ((c.fov.to_radians() / 2.0).tan() * aspect).atan();
    writeln!(
        o,
        "// Written by whitted (to_pov) for a {width}x{height} image, max depth {max_depth}.\n\
         // Render without anti-aliasing, linear 16-bit output:\n\
         //   povray +I<this file> +W{width} +H{height} -A +FN16 File_Gamma=1.0\n\
         #version 3.7;"
    )?;
    writeln!(
        o,
        "global_settings {{ assumed_gamma 1.0 max_trace_level {level} adc_bailout {min_weight} ambient_light rgb {} }}",
        pv(s.ambient)
    )?;
    writeln!(o, "background {{ rgb {} }}", pv(s.background))?;
    // POV-Ray is left-handed: mirroring `right` gives the right-handed image.
    writeln!(
        o,
        "camera {{ perspective location {} look_at {} sky {} up y right -x*{} angle {} }}",
        pv(c.from),
        pv(c.at),
        pv(c.up),
        aspect,
        hfov.to_degrees()
    )?;
    let (blo, bhi) = scene_box(s);
    for l in &s.lights {
        // Distances from the light to the scene: the fall-off's domain.
        let far = [0, 1, 2, 3, 4, 5, 6, 7]
            .map(|k| {
                DVec3::new(
                    if k & 1 == 0 { blo.x } else { bhi.x },
                    if k & 2 == 0 { blo.y } else { bhi.y },
                    if k & 4 == 0 { blo.z } else { bhi.z },
                )
                .distance(l.position)
            })
            .into_iter()
            .fold(0.0, f64::max)
            .max(1e-9);
        let near = (l.position.clamp(blo, bhi).distance(l.position)).max(far * 1e-3);
        let (fade, err) = pov_fade(l.falloff, near, far);
        if err > 1e-4 {
            writeln!(
                o,
                "// fall-off min(1, 1/({} + {} d + {} d^2)) approximated over d in [{near:.4}, {far:.4}]: largest error {:.2}%",
                l.falloff[0],
                l.falloff[1],
                l.falloff[2],
                err * 100.0
            )?;
        }
        write!(
            o,
            "light_source {{ {} color rgb {}",
            pv(l.position),
            pv(l.color * fade.scale)
        )?;
        if fade.power != 0.0 && fade.distance > 0.0 {
            write!(
                o,
                " fade_distance {} fade_power {}",
                fade.distance, fade.power
            )?;
        }
        writeln!(o, " }}")?;
    }
    for (i, m) in s.materials.iter().enumerate() {
        pov_material(&mut o, i, m)?;
    }
    for obj in &s.objects {
        let m = &s.materials[obj.material as usize];
        // Our feelers take k_t alone (docs/method.md); POV-Ray's also fade
        // through an absorbing interior. With k_t = 1 the feeler passes
        // untouched, which `no_shadow` says exactly.
        let modifier = if m.kt == DVec3::ONE && m.absorption.max_element() > 0.0 {
            " no_shadow"
        } else {
            ""
        };
        pov_object(&mut o, &obj.shape, obj.material, modifier)?;
    }
    Ok(o)
}

/// Zero-area triangles are skipped, as `pack` does (they cannot be hit).
fn degenerate(v: &[DVec3; 3]) -> bool {
    (v[1] - v[0]).cross(v[2] - v[0]).length_squared() == 0.0
}

/// One object; `x` (an object modifier or "") goes after its material.
fn pov_object(o: &mut String, shape: &Shape, m: u32, x: &str) -> std::fmt::Result {
    match shape {
        Shape::Sphere { center, radius } => writeln!(
            o,
            "sphere {{ {}, {} material {{ M{m} }}{x} }}",
            pv(*center),
            radius
        ),
        Shape::Plane { point, normal } => {
            let n = normal.normalize();
            writeln!(
                o,
                "plane {{ {}, {} material {{ M{m} }}{x} }}",
                pv(n),
                n.dot(*point)
            )
        }
        Shape::Polygon { vertices } if vertices.len() == 3 => pov_object(
            o,
            &Shape::Triangle {
                vertices: [vertices[0], vertices[1], vertices[2]],
                normals: None,
            },
            m,
            x,
        ),
        Shape::Polygon { vertices } => {
            // Onto the plane `pack` uses (Newell normal, mean offset):
            // POV-Ray wants exactly coplanar points.
            let mut n = DVec3::ZERO;
            for (k, p) in vertices.iter().enumerate() {
                let q = vertices[(k + 1) % vertices.len()];
                n += DVec3::new(
                    (p.y - q.y) * (p.z + q.z),
                    (p.z - q.z) * (p.x + q.x),
                    (p.x - q.x) * (p.y + q.y),
                );
            }
            let n = n.normalize();
            let d = vertices.iter().map(|p| n.dot(*p)).sum::<f64>() / vertices.len() as f64;
            write!(o, "polygon {{ {}", vertices.len() + 1)?;
            for p in vertices.iter().chain(std::iter::once(&vertices[0])) {
                write!(o, ", {}", pv(*p - n * (n.dot(*p) - d)))?;
            }
            writeln!(o, " material {{ M{m} }}{x} }}")
        }
        Shape::Triangle { vertices, normals } => {
            if degenerate(vertices) {
                return writeln!(o, "// zero-area triangle left out");
            }
            match normals {
                None => writeln!(
                    o,
                    "triangle {{ {}, {}, {} material {{ M{m} }}{x} }}",
                    pv(vertices[0]),
                    pv(vertices[1]),
                    pv(vertices[2])
                ),
                Some(n) => writeln!(
                    o,
                    "smooth_triangle {{ {}, {}, {}, {}, {}, {} material {{ M{m} }}{x} }}",
                    pv(vertices[0]),
                    pv(n[0]),
                    pv(vertices[1]),
                    pv(n[1]),
                    pv(vertices[2]),
                    pv(n[2])
                ),
            }
        }
        Shape::Mesh(mesh) => {
            let tris: Vec<&[u32; 3]> = mesh
                .triangles
                .iter()
                .filter(|t| !degenerate(&t.map(|i| mesh.positions[i as usize])))
                .collect();
            if tris.is_empty() {
                return writeln!(o, "// mesh of zero-area triangles left out");
            }
            writeln!(o, "mesh2 {{")?;
            write!(o, "  vertex_vectors {{ {}", mesh.positions.len())?;
            for p in &mesh.positions {
                write!(o, ", {}", pv(*p))?;
            }
            writeln!(o, " }}")?;
            if let Some(ns) = &mesh.normals {
                // One normal per vertex: face_indices index both.
                write!(o, "  normal_vectors {{ {}", ns.len())?;
                for n in ns {
                    write!(o, ", {}", pv(*n))?;
                }
                writeln!(o, " }}")?;
            }
            write!(o, "  face_indices {{ {}", tris.len())?;
            for t in &tris {
                write!(o, ", <{}, {}, {}>", t[0], t[1], t[2])?;
            }
            writeln!(o, " }}\n  material {{ M{m} }}{x}\n}}")
        }
        Shape::Box { min, max } => writeln!(
            o,
            "box {{ {}, {} material {{ M{m} }}{x} }}",
            pv(*min),
            pv(*max)
        ),
        Shape::Quadric {
            coefficients: k,
            clip,
        } => {
            write!(
                o,
                "quadric {{ <{}, {}, {}>, <{}, {}, {}>, <{}, {}, {}>, {}",
                k[0], k[1], k[2], k[3], k[4], k[5], k[6], k[7], k[8], k[9]
            )?;
            if let Some((lo, hi)) = clip {
                write!(o, " clipped_by {{ box {{ {}, {} }} }}", pv(*lo), pv(*hi))?;
            }
            writeln!(o, " material {{ M{m} }}{x} }}")
        }
        Shape::Cone {
            base,
            base_radius,
            apex,
            apex_radius,
        } => {
            // Radii's sign only says which side faces out; POV-Ray shades
            // whichever side faces the viewer.
            let (r0, r1) = (base_radius.abs(), apex_radius.abs());
            if r0 == r1 {
                writeln!(
                    o,
                    "cylinder {{ {}, {}, {} open material {{ M{m} }}{x} }}",
                    pv(*base),
                    pv(*apex),
                    r0
                )
            } else {
                writeln!(
                    o,
                    "cone {{ {}, {}, {}, {} open material {{ M{m} }}{x} }}",
                    pv(*base),
                    r0,
                    pv(*apex),
                    r1
                )
            }
        }
    }
}

#[cfg(test)]
mod pov_tests {
    use super::*;
    use crate::scene::{Light, Mesh, Object};

    fn one(shape: Shape, material: Material) -> Scene {
        let mut s = crate::gen::random_spheres(1, 1);
        s.materials = vec![Material::default(), material];
        s.objects = vec![Object { shape, material: 1 }];
        s
    }

    fn ball(material: Material) -> Scene {
        one(
            Shape::Sphere {
                center: DVec3::ZERO,
                radius: 1.0,
            },
            material,
        )
    }

    /// The `#declare M1 = ...` line.
    fn m1(text: &str) -> &str {
        text.lines()
            .find(|l| l.starts_with("#declare M1 "))
            .unwrap()
    }

    #[test]
    fn arguments_are_checked() {
        let s = crate::gen::random_spheres(5, 1);
        assert!(to_pov(&s, 0, 10, 5, 0.0).is_err());
        assert!(to_pov(&s, 10, 0, 5, 0.0).is_err());
        assert!(to_pov(&s, POV_MAX_IMAGE_SIZE + 1, 10, 5, 0.0).is_err());
        // No wrapping: u32::MAX + 1 is not level 0.
        let e = to_pov(&s, 10, 10, u32::MAX, 0.0).unwrap_err().to_string();
        assert!(e.contains("max_trace_level"), "{e}");
        assert!(to_pov(&s, 10, 10, 256, 0.0).is_err());
        let t = to_pov(&s, 10, 10, 255, 0.0).unwrap();
        assert!(t.contains("max_trace_level 256 "));
        assert!(to_pov(&s, 10, 10, 0, 0.0)
            .unwrap()
            .contains("max_trace_level 1 "));
        for w in [f32::NAN, -0.1, 1.5, f32::INFINITY] {
            assert!(to_pov(&s, 10, 10, 5, w).is_err(), "{w}");
        }
        let mut bad = s.clone();
        bad.lights[0].position.x = f64::NAN;
        assert!(to_pov(&bad, 10, 10, 5, 0.0).is_err());
        let mut bad = s.clone();
        bad.objects[0].material = 99;
        assert!(to_pov(&bad, 10, 10, 5, 0.0).is_err());
    }

    #[test]
    fn camera_angle_is_horizontal() {
        let mut s = crate::gen::random_spheres(5, 1);
        s.camera.fov = 90.0;
        // tan(45°) · 2 = tan(hfov/2) → hfov = 2·atan(2) = 126.87°.
        let t = to_pov(&s, 200, 100, 5, 0.0).unwrap();
        let cam = t.lines().find(|l| l.starts_with("camera")).unwrap();
        assert!(cam.contains("right -x*2 "), "{cam}");
        assert!(cam.contains("angle 126.869"), "{cam}");
    }

    #[test]
    fn opaque_material_maps_exactly() {
        let m = Material {
            ka: DVec3::new(0.1, 0.2, 0.0),
            kd: DVec3::new(0.8, 0.0, 0.4),
            ksr: 0.5,
            nr: 30.0,
            kr: DVec3::new(0.3, 0.2, 0.1),
            ..Material::default()
        };
        let t = to_pov(&ball(m), 10, 10, 5, 0.0).unwrap();
        let l = m1(&t);
        // Pigment k_d / max k_d, its green floored so ambient can carry 0.2.
        assert!(l.contains("rgbft <1, 0.000001, 0.5, 0, 0>"), "{l}");
        assert!(l.contains("diffuse 0.8 "), "{l}");
        assert!(l.contains("ambient rgb <0.1, 200000"), "{l}");
        assert!(l.contains("phong 0.5 phong_size 30"), "{l}");
        assert!(l.contains("reflection { rgb <0.3, 0.2, 0.1> }"), "{l}");
        assert!(!l.contains("interior"), "{l}");
    }

    #[test]
    fn grey_transmission_is_one_layer() {
        let m = Material {
            ka: DVec3::ZERO,
            kd: DVec3::splat(0.05),
            kt: DVec3::splat(0.9),
            ior: 1.5,
            ..Material::default()
        };
        let t = to_pov(&ball(m), 10, 10, 5, 0.0).unwrap();
        let l = m1(&t);
        assert_eq!(l.matches("texture {").count(), 1, "{l}");
        // α = 1 − 0.9: diffuse 0.05 / 0.1 keeps k_d = 0.05.
        assert!(l.contains("rgbft <1, 1, 1, 0, 0.9>"), "{l}");
        assert!(l.contains("diffuse 0.5"), "{l}");
        assert!(l.contains("interior { ior 1.5 }"), "{l}");
    }

    #[test]
    fn coloured_transmission_is_two_layers() {
        let m = Material {
            kt: DVec3::new(0.2, 0.5, 0.8),
            ..Material::default()
        };
        let t = to_pov(&ball(m), 10, 10, 5, 0.0).unwrap();
        let l = m1(&t);
        assert_eq!(l.matches("texture {").count(), 2, "{l}");
        // Bottom layer first: filter 2·k_t under a top layer transmitting
        // 0.5, so light through both is k_t.
        let bottom = l.find("rgbft <0.4, 1, 1.6, 1, 0>").expect(l);
        let top = l.find(", 0, 0.5>").expect(l);
        assert!(bottom < top, "{l}");
    }

    #[test]
    fn absorption_is_exponential_fade() {
        let m = Material {
            kd: DVec3::ZERO,
            ka: DVec3::ZERO,
            kt: DVec3::ONE,
            ior: 1.3,
            absorption: DVec3::new(0.5, 1.0, 2.0),
            ..Material::default()
        };
        let t = to_pov(&ball(m), 10, 10, 5, 0.0).unwrap();
        let l = m1(&t);
        // exp(−(1 − c)·d/0.5) = exp(−σ d) for c = 1 − σ/2.
        assert!(
            l.contains("fade_distance 0.5 fade_power 1001 fade_color rgb <0.75, 0.5, 0>"),
            "{l}"
        );
        // k_t = 1: our feelers pass untouched, so POV-Ray must not fade them.
        assert!(t.contains("material { M1 } no_shadow }"), "{t}");
    }

    #[test]
    fn transmission_highlight_is_noted() {
        let m = Material {
            kst: 0.4,
            nt: 12.0,
            kt: DVec3::splat(0.5),
            ..Material::default()
        };
        let t = to_pov(&ball(m), 10, 10, 5, 0.0).unwrap();
        assert!(t.contains("// kst 0.4 (V.T_L)^12: POV-Ray has no transmission highlight"));
    }

    #[test]
    fn falloff_exact_forms() {
        for (c, d) in [([1.0, 0.0, 0.04], 5.0), ([2.0, 0.5, 0.0], 4.0)] {
            let (f, err) = pov_fade(c, 0.5, 30.0);
            assert!(err < 1e-12, "{c:?}: {err}");
            assert!((f.distance - d).abs() < 1e-12, "{c:?}: {f:?}");
        }
        // c1 = 0: a power law, from where the clamp stops.
        let (f, err) = pov_fade([0.0, 0.0, 0.01], 10.0, 30.0);
        assert!(err < 1e-5, "{err}");
        assert_eq!(f.power, 2.0);
        // No fall-off, and a constant one.
        assert_eq!(pov_fade([1.0, 0.0, 0.0], 1.0, 9.0).0.power, 0.0);
        let (f, _) = pov_fade([4.0, 0.0, 0.0], 1.0, 9.0);
        assert_eq!((f.scale, f.power), (0.25, 0.0));
    }

    #[test]
    fn falloff_fit_is_close() {
        let c = [0.5, 0.2, 0.05];
        let (f, err) = pov_fade(c, 1.0, 8.0);
        // Largest error, checked independently at 1000 distances.
        let worst = (0..1000)
            .map(|i| 1.0 + 7.0 * i as f64 / 999.0)
            .map(|d| (f.at(d) / falloff_at(c, d) - 1.0).abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.09, "{worst}");
        assert!((worst - err).abs() < 0.01, "{worst} vs {err}");
    }

    #[test]
    fn falloff_writes_fade() {
        let mut s = ball(Material::default());
        s.lights = vec![Light {
            position: DVec3::new(0.0, 0.0, 5.0),
            color: DVec3::ONE,
            falloff: [1.0, 0.0, 0.25],
        }];
        let t = to_pov(&s, 10, 10, 5, 0.0).unwrap();
        assert!(
            t.contains(
                "light_source { <0, 0, 5> color rgb <0.5, 0.5, 0.5> fade_distance 2 fade_power 2 }"
            ),
            "{t}"
        );
    }

    #[test]
    fn every_primitive() {
        let v = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        let tri = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)];
        let shapes = vec![
            Shape::Plane {
                point: v(0.0, 0.0, -2.0),
                normal: v(0.0, 0.0, 3.0),
            },
            Shape::Polygon {
                vertices: vec![
                    v(0.0, 0.0, 0.0),
                    v(2.0, 0.0, 0.0),
                    v(2.0, 2.0, 0.0),
                    v(1.0, 1.0, 0.0),
                ],
            },
            Shape::Polygon {
                vertices: tri.to_vec(),
            },
            Shape::Triangle {
                vertices: tri,
                normals: Some(Box::new([DVec3::Z; 3])),
            },
            Shape::Triangle {
                vertices: [tri[0], tri[1], tri[1] * 2.0],
                normals: None,
            },
            Shape::Mesh(Box::new(Mesh {
                positions: vec![tri[0], tri[1], tri[2], v(1.0, 1.0, 1.0)],
                normals: Some(vec![DVec3::Z; 4]),
                triangles: vec![[0, 1, 2], [1, 3, 2], [0, 1, 1]],
            })),
            Shape::Box {
                min: v(-1.0, -1.0, -1.0),
                max: v(1.0, 2.0, 3.0),
            },
            Shape::Quadric {
                coefficients: [1.0, 1.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -0.5],
                clip: Some((v(-2.0, -2.0, 0.0), v(2.0, 2.0, 2.0))),
            },
            Shape::Cone {
                base: v(0.0, 0.0, 0.0),
                base_radius: -1.0,
                apex: v(0.0, 0.0, 2.0),
                apex_radius: -0.5,
            },
            Shape::Cone {
                base: v(0.0, 0.0, 0.0),
                base_radius: 0.5,
                apex: v(0.0, 0.0, 2.0),
                apex_radius: 0.5,
            },
        ];
        let mut s = crate::gen::random_spheres(1, 1);
        s.objects = shapes
            .into_iter()
            .map(|shape| Object { shape, material: 0 })
            .collect();
        let t = to_pov(&s, 10, 10, 5, 0.0).unwrap();
        assert!(t.contains("plane { <0, 0, 1>, -2 "), "{t}");
        assert!(t.contains("polygon { 5, <0, 0, 0>, <2, 0, 0>, <2, 2, 0>, <1, 1, 0>, <0, 0, 0> "));
        // A three-vertex polygon is a triangle (as pack makes it); the
        // zero-area triangle is left out, as pack leaves it out.
        assert_eq!(t.matches("\ntriangle {").count(), 1, "{t}");
        assert!(t.contains("// zero-area triangle left out"));
        assert_eq!(t.matches("smooth_triangle {").count(), 1);
        assert!(t.contains("vertex_vectors { 4, "));
        assert!(t.contains("normal_vectors { 4, "));
        assert!(
            t.contains("face_indices { 2, <0, 1, 2>, <1, 3, 2> }"),
            "{t}"
        );
        assert!(t.contains("box { <-1, -1, -1>, <1, 2, 3> "));
        assert!(t.contains(
            "quadric { <1, 1, -1>, <0, 0, 0>, <0, 0, 0>, -0.5 clipped_by { box { <-2, -2, 0>, <2, 2, 2> } }"
        ));
        assert!(t.contains("cone { <0, 0, 0>, 1, <0, 0, 2>, 0.5 open "));
        assert!(t.contains("cylinder { <0, 0, 0>, <0, 0, 2>, 0.5 open "));
        // The text parses as POV-Ray's: balanced braces.
        assert_eq!(t.matches('{').count(), t.matches('}').count());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn nff_round_trips_spheres_and_lights() {
        let mut s = crate::gen::random_spheres(20, 3);
        let text = to_nff(&s).unwrap();
        let back = crate::scene::parse_str(&text, Path::new("x.nff")).unwrap();
        assert_eq!(back.objects.len(), 21);
        assert_eq!(back.lights.len(), 3);
        assert_eq!(back.lights[1].color, s.lights[1].color);
        assert_eq!(back.objects[4].shape, s.objects[4].shape);
        s.objects.push(crate::scene::Object {
            shape: Shape::Plane {
                point: DVec3::ZERO,
                normal: DVec3::Z,
            },
            material: 0,
        });
        assert!(to_nff(&s).is_err(), "a plane has no NFF form");
    }

    #[test]
    fn pov_has_every_object() {
        let s = crate::gen::random_spheres(50, 1);
        let t = to_pov(&s, 320, 240, 5, 0.0).unwrap();
        assert_eq!(t.matches("sphere {").count(), 50);
        assert_eq!(t.matches("polygon {").count(), 1);
        assert!(t.contains("max_trace_level 6"));
        assert!(t.contains("right -x*1.3333"));
    }
}
