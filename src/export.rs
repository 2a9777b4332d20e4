//! Scene → other renderers' formats: NFF (the SPD's format) and POV-Ray
//! 3.7 scene language, for side-by-side timing against POV-Ray.

use crate::scene::{Material, Scene, Shape};
use anyhow::{bail, Result};
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

fn pov_texture(m: &Material) -> String {
    // POV multiplies ambient and diffuse by the pigment: the pigment is the
    // diffuse colour and ambient is expressed relative to it.
    let kd = m.kd;
    let pig = if kd.max_element() > 0.0 {
        kd
    } else {
        m.ka.max(DVec3::splat(1e-6))
    };
    let amb = DVec3::new(
        m.ka.x / pig.x.max(1e-9),
        m.ka.y / pig.y.max(1e-9),
        m.ka.z / pig.z.max(1e-9),
    );
    let diffuse = if kd.max_element() > 0.0 { 1.0 } else { 0.0 };
    let mut t = format!(
        "texture {{ pigment {{ rgbf <{}, {}, {}, {}> }} finish {{ ambient rgb {} diffuse {} phong {} phong_size {} reflection {{ rgb {} }} }} }}",
        pig.x,
        pig.y,
        pig.z,
        m.kt.max_element(),
        pv(amb),
        diffuse,
        m.ksr,
        m.nr,
        pv(m.kr)
    );
    if m.kt.max_element() > 0.0 {
        write!(t, " interior {{ ior {} }}", m.ior).unwrap();
    }
    t
}

/// POV-Ray 3.7 scene text: same camera (vertical field of view, right-handed
/// coordinates), lights, materials and primitives; `max_depth` generations
/// of secondary rays (POV counts the eye ray as level 1) and `min_weight`
/// as ADC bailout.
pub fn to_pov(
    s: &Scene,
    width: u32,
    height: u32,
    max_depth: u32,
    min_weight: f32,
) -> Result<String> {
    let mut o = String::new();
    let c = &s.camera;
    let aspect = width as f64 / height as f64;
    let hfov = 2.0 * ((c.fov.to_radians() / 2.0).tan() * aspect).atan();
    writeln!(o, "#version 3.7;")?;
    writeln!(
        o,
        "global_settings {{ assumed_gamma 1.0 max_trace_level {} adc_bailout {} ambient_light rgb {} }}",
        max_depth + 1,
        min_weight,
        pv(s.ambient)
    )?;
    writeln!(o, "background {{ rgb {} }}", pv(s.background))?;
    // POV is left-handed: mirroring `right` gives the right-handed image.
    writeln!(
        o,
        "camera {{ perspective location {} look_at {} sky {} up y right -x*{} angle {} }}",
        pv(c.from),
        pv(c.at),
        pv(c.up),
        aspect,
        hfov.to_degrees()
    )?;
    for l in &s.lights {
        writeln!(
            o,
            "light_source {{ {} color rgb {} }}",
            pv(l.position),
            pv(l.color)
        )?;
    }
    for (i, m) in s.materials.iter().enumerate() {
        writeln!(o, "#declare M{i} = material {{ {} }}", pov_texture(m))?;
    }
    for obj in &s.objects {
        let m = obj.material;
        match &obj.shape {
            Shape::Sphere { center, radius } => writeln!(
                o,
                "sphere {{ {}, {} material {{ M{m} }} }}",
                pv(*center),
                radius
            )?,
            Shape::Plane { point, normal } => {
                let n = normal.normalize();
                writeln!(
                    o,
                    "plane {{ {}, {} material {{ M{m} }} }}",
                    pv(n),
                    n.dot(*point)
                )?
            }
            Shape::Polygon { vertices } => {
                write!(o, "polygon {{ {}", vertices.len() + 1)?;
                for p in vertices.iter().chain(std::iter::once(&vertices[0])) {
                    write!(o, ", {}", pv(*p))?;
                }
                writeln!(o, " material {{ M{m} }} }}")?;
            }
            Shape::Triangle { vertices, normals } => match normals {
                None => writeln!(
                    o,
                    "triangle {{ {}, {}, {} material {{ M{m} }} }}",
                    pv(vertices[0]),
                    pv(vertices[1]),
                    pv(vertices[2])
                )?,
                Some(n) => writeln!(
                    o,
                    "smooth_triangle {{ {}, {}, {}, {}, {}, {} material {{ M{m} }} }}",
                    pv(vertices[0]),
                    pv(n[0]),
                    pv(vertices[1]),
                    pv(n[1]),
                    pv(vertices[2]),
                    pv(n[2])
                )?,
            },
            Shape::Mesh(mesh) => {
                writeln!(o, "mesh {{")?;
                for t in &mesh.triangles {
                    let p = t.map(|i| mesh.positions[i as usize]);
                    match &mesh.normals {
                        None => writeln!(
                            o,
                            "  triangle {{ {}, {}, {} }}",
                            pv(p[0]),
                            pv(p[1]),
                            pv(p[2])
                        )?,
                        Some(ns) => {
                            let n = t.map(|i| ns[i as usize]);
                            writeln!(
                                o,
                                "  smooth_triangle {{ {}, {}, {}, {}, {}, {} }}",
                                pv(p[0]),
                                pv(n[0]),
                                pv(p[1]),
                                pv(n[1]),
                                pv(p[2]),
                                pv(n[2])
                            )?
                        }
                    }
                }
                writeln!(o, "  material {{ M{m} }} }}")?;
            }
            Shape::Box { min, max } => writeln!(
                o,
                "box {{ {}, {} material {{ M{m} }} }}",
                pv(*min),
                pv(*max)
            )?,
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
                writeln!(o, " material {{ M{m} }} }}")?;
            }
            Shape::Cone {
                base,
                base_radius,
                apex,
                apex_radius,
            } => writeln!(
                o,
                "cone {{ {}, {}, {}, {} open material {{ M{m} }} }}",
                pv(*base),
                base_radius.abs(),
                pv(*apex),
                apex_radius.abs()
            )?,
        }
    }
    Ok(o)
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
