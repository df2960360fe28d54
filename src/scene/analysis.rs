//! What a scene uses, found once at load: the material lobes, the kinds of light, the textures,
//! and from them which integrator features a render of it can need. `lightsplit info` prints
//! it; the renderer's specialisation (issue 8) is chosen from it.

use std::fmt;

use super::{Geometry, Light, Material, Scene};

/// The kinds of light a scene has, each with a count (lights of zero power left out: they are
/// never sampled).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LightKinds {
    pub point: usize,
    pub spot: usize,
    pub sun: usize,
    pub sky: usize,
    pub cloudy_sky: usize,
    pub environment: usize,
    pub emissive_meshes: usize,
    pub emissive_spheres: usize,
}

impl LightKinds {
    /// Lights that a path can hit (a sun's disc, a sky, an emissive shape): with only point and
    /// spot lights, BSDF sampling never finds a light and no MIS weight is needed.
    pub fn hittable(&self) -> usize {
        self.sun
            + self.sky
            + self.cloudy_sky
            + self.environment
            + self.emissive_meshes
            + self.emissive_spheres
    }

    /// Lights at infinity, which an escaping ray looks up.
    pub fn distant(&self) -> usize {
        self.sun + self.sky + self.cloudy_sky + self.environment
    }

    pub fn total(&self) -> usize {
        self.point + self.spot + self.hittable()
    }
}

/// The material lobes a scene's shapes use (materials no shape uses are not counted).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Lobes {
    pub diffuse: bool,
    pub mirror: bool,
    pub glass: bool,
    pub glossy: bool,
    /// A glossy material with a non-black diffuse base.
    pub glossy_base: bool,
}

impl Lobes {
    /// Any specular-like (S) scattering: without it there are no caustics.
    pub fn specular(&self) -> bool {
        self.mirror || self.glass || self.glossy
    }
}

/// The analysis of one scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Analysis {
    pub lobes: Lobes,
    pub lights: LightKinds,
    /// Materials (used by shapes) that read a colour texture.
    pub color_textures: usize,
    /// Materials (used by shapes) that read a bump map.
    pub bump_maps: usize,
    /// Meshes with vertex colours (multiplying their material's colour, as a texture does).
    pub vertex_colours: usize,
    /// Triangles in the scene, each instance's counted.
    pub triangles: usize,
    /// Triangles held in memory: a mesh shared by several instances counted once.
    pub stored_triangles: usize,
    /// Shapes that place a shared mesh, and how many distinct meshes they place.
    pub instances: usize,
    pub shared_meshes: usize,
    pub spheres: usize,
    /// Shapes (Embree geometries).
    pub shapes: usize,
    /// Shapes with a cut-out (alpha), whose hits both backends test.
    pub cut_outs: usize,
}

impl Analysis {
    /// Whether a render reads textures or vertex colours: without them a hit computes neither
    /// its texture coordinates nor its colour.
    pub fn textured(&self) -> bool {
        self.color_textures + self.bump_maps + self.vertex_colours > 0
    }

    pub fn of(scene: &Scene) -> Analysis {
        let mut used = vec![false; scene.materials.len()];
        let mut a = Analysis {
            lobes: Lobes::default(),
            lights: LightKinds::default(),
            color_textures: 0,
            bump_maps: 0,
            vertex_colours: 0,
            triangles: scene.triangle_count(),
            stored_triangles: 0,
            instances: 0,
            shared_meshes: 0,
            spheres: 0,
            shapes: scene.shapes.len(),
            cut_outs: super::cutout::Cutouts::new(scene)
                .map_or(0, |c| (0..scene.shapes.len() as u32).filter(|&s| c.cuts(s)).count()),
        };
        let mut shared = std::collections::HashSet::new();
        for shape in &scene.shapes {
            if let Geometry::Triangles(mesh) = &shape.geometry {
                a.vertex_colours += mesh.attributes.as_ref().is_some_and(|at| at.colors.is_some()) as usize;
                match mesh.instance {
                    None => a.stored_triangles += mesh.indices.len(),
                    Some(_) => {
                        a.instances += 1;
                        if shared.insert(mesh.arrays()) {
                            a.stored_triangles += mesh.indices.len();
                            a.shared_meshes += 1;
                        }
                    }
                }
            }
        }
        for shape in &scene.shapes {
            if let Some(u) = used.get_mut(shape.material as usize) {
                *u = true;
            }
            let visible = match &shape.geometry {
                Geometry::Sphere { radius, .. } => {
                    a.spheres += 1;
                    *radius > 0.0
                }
                Geometry::Triangles(mesh) => {
                    (0..mesh.indices.len() as u32).any(|t| mesh.triangle_area(t) > 0.0)
                }
            };
            if shape.is_emissive() && visible {
                match shape.geometry {
                    Geometry::Sphere { .. } => a.lights.emissive_spheres += 1,
                    Geometry::Triangles(_) => a.lights.emissive_meshes += 1,
                }
            }
        }
        for (m, material) in scene.materials.iter().enumerate() {
            if !used[m] {
                continue;
            }
            // A one-sided material is its inner one; a blend both of its own.
            let mut stack = vec![material];
            while let Some(material) = stack.pop() {
                match material {
                    Material::Front(inner) => stack.push(inner),
                    Material::Blend(b) => stack.extend([&b.a, &b.b]),
                    Material::Conductor(c) => match c.facets {
                        Some(_) => a.lobes.glossy = true,
                        None => a.lobes.mirror = true,
                    },
                    Material::Dielectric(d) => {
                        a.lobes.glass = true;
                        a.lobes.glossy |= d.facets.is_some();
                    }
                    Material::Plastic(p) => {
                        a.lobes.diffuse = true;
                        a.lobes.glossy_base = true;
                        match p.facets {
                            Some(_) => a.lobes.glossy = true,
                            None => a.lobes.mirror = true,
                        }
                    }
                    Material::Diffuse { .. } => a.lobes.diffuse = true,
                    Material::Mirror { .. } => a.lobes.mirror = true,
                    Material::Glass { .. } => a.lobes.glass = true,
                    Material::Pbr { .. } => {
                        // Its lobes depend on textures and roughness: all of them, conservatively.
                        a.lobes.glossy = true;
                        a.lobes.glossy_base = true;
                        a.lobes.diffuse = true;
                    }
                    Material::Layered(l) => {
                        a.lobes.glossy = true;
                        a.lobes.glossy_base = true;
                        a.lobes.diffuse = true;
                        a.lobes.glass |= l.layers.transmission > 0.0;
                    }
                    Material::Glossy { base, .. } => {
                        a.lobes.glossy = true;
                        a.lobes.glossy_base |=
                            base.max_element() > 0.0 || scene.maps(m as u32).color.is_some();
                    }
                }
            }
            let maps = scene.maps(m as u32);
            a.color_textures += maps.color.is_some() as usize
                + maps.metal_rough.is_some() as usize
                + maps.transmission.is_some() as usize
                + maps.emission.is_some() as usize
                + 2 * maps.spec_gloss.is_some() as usize
                + maps.layer.count();
            a.bump_maps += maps.bump.is_some() as usize
                + maps.normal.is_some() as usize
                + maps.height.is_some() as usize;
        }
        for light in &scene.lights {
            let bright = |v: glam::Vec3| v.max_element() > 0.0;
            match light {
                Light::Point { intensity, .. } if bright(*intensity) => a.lights.point += 1,
                Light::Spot { intensity, .. } if bright(*intensity) => a.lights.spot += 1,
                Light::Sun { radiance, .. } if bright(*radiance) => a.lights.sun += 1,
                Light::Sky { radiance, .. } if bright(*radiance) => a.lights.sky += 1,
                Light::CloudySky { .. } => a.lights.cloudy_sky += 1,
                Light::Environment { map, .. } if map.image.pixels.iter().any(|p| bright(*p)) => {
                    a.lights.environment += 1
                }
                _ => {}
            }
        }
        a
    }

    /// Whether the scene reflects light diffusely at all (the paper's D vertices): without,
    /// every pixel is `emitted` and there is nothing to filter.
    pub fn diffuse(&self) -> bool {
        self.lobes.diffuse || self.lobes.glossy_base
    }
}

impl fmt::Display for Analysis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let list = |items: &[(&str, bool)]| {
            let names: Vec<&str> = items.iter().filter(|(_, on)| *on).map(|(n, _)| *n).collect();
            if names.is_empty() {
                "none".to_string()
            } else {
                names.join(", ")
            }
        };
        let l = &self.lobes;
        write!(f, "geometry: {} triangles, {} spheres", self.triangles, self.spheres)?;
        if self.instances > 0 {
            write!(
                f,
                " ({} instances of {} shared meshes; {} triangles stored)",
                self.instances, self.shared_meshes, self.stored_triangles
            )?;
        }
        if self.cut_outs > 0 {
            write!(f, "; {} shapes with cut-outs (alpha-tested hits)", self.cut_outs)?;
        }
        writeln!(f)?;
        writeln!(
            f,
            "material lobes: {}",
            list(&[
                ("diffuse", l.diffuse),
                ("mirror", l.mirror),
                ("glass", l.glass),
                ("glossy (GGX)", l.glossy),
                ("glossy base (diffuse)", l.glossy_base),
            ])
        )?;
        let k = &self.lights;
        let counted = |n: usize, name: &str| (n > 0).then(|| format!("{n} {name}"));
        let lights: Vec<String> = [
            counted(k.point, "point"),
            counted(k.spot, "spot"),
            counted(k.sun, "sun"),
            counted(k.sky, "uniform sky"),
            counted(k.cloudy_sky, "cloudy sky"),
            counted(k.environment, "environment map"),
            counted(k.emissive_meshes, "emissive mesh"),
            counted(k.emissive_spheres, "emissive sphere"),
        ]
        .into_iter()
        .flatten()
        .collect();
        writeln!(f, "lights: {}", if lights.is_empty() { "none".to_string() } else { lights.join(", ") })?;
        write!(f, "textures: {} colour, {} bump", self.color_textures, self.bump_maps)?;
        match self.vertex_colours {
            0 => writeln!(f)?,
            n => writeln!(f, "; {n} meshes with vertex colours")?,
        }
        writeln!(f, "so a render of it needs:")?;
        let need = |f: &mut fmt::Formatter<'_>, what: &str, needed: bool, why: &str| {
            writeln!(f, "{}", need_line(what, needed, why))
        };
        need(
            f,
            "MIS between light and BSDF",
            k.hittable() > 0,
            if k.hittable() > 0 {
                "a path can hit a light"
            } else {
                "only point and spot lights, which no path hits"
            },
        )?;
        need(
            f,
            "the caustic component",
            l.specular() && self.diffuse(),
            "needs a specular-like bounce after a diffuse one",
        )?;
        need(f, "lookups at infinity", k.distant() > 0, "a sun or a sky, seen by escaping rays")?;
        need(f, "texture evaluation", self.textured(), "materials that read a texture, or vertex colours")?;
        need(f, "the GGX lobe", l.glossy, "glossy materials")?;
        need(f, "Fresnel refraction", l.glass, "glass")?;
        Ok(())
    }
}

/// The warning for a scene with no light source at all (no light, no emissive surface, no
/// environment): its image is black, and the render says so before it starts.
pub fn no_light_warning(scene: &Scene) -> Option<String> {
    (Analysis::of(scene).lights.total() == 0).then(|| {
        "the scene has no light source (no light, no emissive surface, no environment): its image \
         will be black; add a light, or `--environment white`"
            .to_string()
    })
}

/// One line of what a render needs: the feature, yes or no, and why.
pub fn need_line(what: &str, needed: bool, why: &str) -> String {
    format!("  {what:34} {:3}  ({why})", if needed { "yes" } else { "no" })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::file::parse;
    use std::path::Path;

    fn analyse(body: &str) -> Analysis {
        let text = format!("[camera]\nposition = [0, 1, -4]\nlook_at = [0, 0, 0]\n{body}");
        Analysis::of(&parse(Path::new("a.toml"), &text).expect("parses"))
    }

    #[test]
    fn a_diffuse_scene_under_a_point_light_needs_no_mis_and_no_caustics() {
        let a = analyse(
            "[[shape]]\ntype = \"sphere\"\nradius = 1\n\
             [[light]]\ntype = \"point\"\nposition = [0, 3, 0]\nintensity = [1, 1, 1]\n",
        );
        assert!(a.lobes.diffuse && !a.lobes.specular());
        assert_eq!((a.lights.point, a.lights.hittable()), (1, 0));
        let text = a.to_string();
        assert!(text.contains("MIS between light and BSDF         no"), "{text}");
        assert!(text.contains("the caustic component              no"), "{text}");
    }

    #[test]
    fn lights_lobes_and_textures_are_found_and_dark_ones_left_out() {
        let a = analyse(
            "[[texture]]\nname = \"c\"\ntype = \"checker\"\nsize = 1\n\
             [[material]]\nname = \"g\"\ntype = \"glossy\"\nroughness = 0.2\ntexture = \"c\"\n\
             [[material]]\nname = \"unused\"\ntype = \"glass\"\n\
             [[shape]]\ntype = \"sphere\"\nradius = 1\nmaterial = \"g\"\n\
             [[shape]]\ntype = \"sphere\"\ncenter = [3, 0, 0]\nradius = 0.5\nemission = [2, 2, 2]\n\
             [[shape]]\ntype = \"sphere\"\ncenter = [3, 0, 0]\nradius = 0\nemission = [2, 2, 2]\n\
             [[light]]\ntype = \"sky\"\nradiance = [0.5, 0.5, 0.5]\n\
             [[light]]\ntype = \"point\"\nposition = [0, 3, 0]\nintensity = [0, 0, 0]\n",
        );
        assert!(a.lobes.glossy && a.lobes.glossy_base && a.lobes.diffuse && !a.lobes.glass);
        assert_eq!(a.lights, LightKinds { sky: 1, emissive_spheres: 1, ..Default::default() });
        assert_eq!((a.color_textures, a.bump_maps, a.spheres), (1, 0, 3));
        let text = a.to_string();
        assert!(text.contains("the caustic component              yes"), "{text}");
        assert!(text.contains("lights: 1 uniform sky, 1 emissive sphere"), "{text}");
    }
}
