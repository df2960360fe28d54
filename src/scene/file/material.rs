//! `[[material]]`: diffuse, mirror, glass and glossy materials by name, with the textures they
//! read instead of their colour (`texture`) and as a height field (`bump`).

use std::collections::HashMap;

use glam::Vec3;
use serde::Deserialize;

use super::typed::{Table, Typed};
use super::{v3, Ctx, Exact, Wide, F, V3};
use crate::scene::texture::Texture;
use crate::scene::{Maps, Material, SceneError};

/// The keys every material takes.
#[derive(Deserialize)]
pub(super) struct MaterialCommon {
    name: String,
    texture: Option<String>,
    bump: Option<String>,
    bump_height: Option<F>,
}

/// A material's type and its own keys.
#[derive(Deserialize)]
#[serde(rename_all = "lowercase")]
pub(super) enum MaterialKind {
    Diffuse(Diffuse),
    Mirror(Mirror),
    Glass(Glass),
    Glossy(Glossy),
}

impl Typed for MaterialKind {
    type Common = MaterialCommon;
    const SECTION: &'static str = "material";
}

/// Lambertian reflection.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Diffuse {
    color: Option<V3>,
}

/// Perfect specular reflection.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Mirror {
    color: Option<V3>,
}

/// A smooth dielectric.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Glass {
    color: Option<V3>,
    ior: Option<F>,
}

/// A GGX lobe over a diffuse base.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Glossy {
    color: Option<V3>,
    roughness: Option<F>,
    base: Option<V3>,
}

/// The materials of a file, the textures each reads, and their indices by name.
pub(super) struct Materials {
    pub materials: Vec<Material>,
    pub maps: Vec<Maps>,
    pub ids: HashMap<String, u32>,
}

/// Resolves the materials against the textures (`textures`, indexed by `texture_ids`).
pub(super) fn materials(
    ctx: &Ctx,
    tables: &[Table<MaterialKind>],
    textures: &[Texture],
    texture_ids: &HashMap<String, u32>,
) -> Result<Materials, SceneError> {
    let mut out = Materials { materials: Vec::new(), maps: Vec::new(), ids: HashMap::new() };
    for m in tables {
        let span = m.span.clone();
        let c = &m.common;
        if out.ids.contains_key(&c.name) {
            return ctx.err(span, format!("material `{}` is defined twice", c.name));
        }
        let unit = |v: Option<V3>, default: f32, message: &str| -> Result<Vec3, SceneError> {
            let v = v3(v.unwrap_or(Exact([Wide(default as f64); 3])));
            if v.min_element() < 0.0 || v.max_element() > 1.0 {
                ctx.err(span.clone(), message)
            } else {
                Ok(v)
            }
        };
        let material = match &m.of_type {
            MaterialKind::Diffuse(d) => {
                Material::Diffuse { albedo: unit(d.color, 0.8, "a diffuse `color` must lie in [0, 1]")? }
            }
            MaterialKind::Mirror(d) => {
                Material::Mirror { color: unit(d.color, 1.0, "a `color` must lie in [0, 1]")? }
            }
            MaterialKind::Glass(g) => {
                let color = unit(g.color, 1.0, "a `color` must lie in [0, 1]")?;
                let ior = g.ior.map_or(1.5, |i| i.0);
                if ior <= 0.0 {
                    return ctx.err(span, "`ior` must be positive");
                }
                Material::Glass { ior, color }
            }
            MaterialKind::Glossy(g) => {
                let specular = unit(g.color, 0.9, "a glossy `color` must lie in [0, 1]")?;
                let base = unit(g.base, 0.0, "a glossy `base` must lie in [0, 1]")?;
                let roughness = g.roughness.map_or(0.3, |r| r.0);
                if !(0.0..=1.0).contains(&roughness) {
                    return ctx.err(span, "`roughness` must lie in [0, 1]");
                }
                Material::Glossy { specular, roughness, base }
            }
        };
        let texture_id = |name: &String| match texture_ids.get(name) {
            Some(&t) => Ok(t),
            None => ctx.err(span.clone(), format!("unknown texture `{name}`")),
        };
        let color = match &c.texture {
            Some(_) if !matches!(material, Material::Diffuse { .. } | Material::Glossy { .. }) => {
                return ctx
                    .err(span, "only diffuse and glossy materials take a `texture` (the albedo or the base)")
            }
            Some(name) => Some(texture_id(name)?),
            None => None,
        };
        let bump = match &c.bump {
            Some(name) => {
                let t = texture_id(name)?;
                if !textures[t as usize].is_solid() {
                    return ctx.err(
                        span,
                        format!("`bump` needs a solid texture (checker or noise); `{name}` is not"),
                    );
                }
                Some((t, c.bump_height.map_or(0.02, |h| h.0)))
            }
            None if c.bump_height.is_some() => return ctx.err(span, "`bump_height` needs a `bump` texture"),
            None => None,
        };
        out.ids.insert(c.name.clone(), out.materials.len() as u32);
        out.materials.push(material);
        out.maps.push(Maps { color, bump, ..Maps::default() });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::file::tests::{error_line, parse_str, MINIMAL};

    #[test]
    fn material_keys_belong_to_their_types() {
        let glossy = "[[material]]\nname = \"g\"\ntype = \"glossy\"\n";
        let s =
            parse_str(&format!("{MINIMAL}{glossy}roughness = 0.5\nbase = [0.5, 0, 0]\n")).expect("parses");
        let Material::Glossy { roughness, base, specular } = s.materials[0] else {
            panic!("{:?}", s.materials)
        };
        // The GGX alpha of roughness 0.5 is 0.25 (`render::bsdf::alpha`, tested there).
        assert_eq!((roughness, base, specular), (0.5, Vec3::new(0.5, 0.0, 0.0), Vec3::splat(0.9)));
        for (extra, needle) in
            [("roughness = 1.5\n", "roughness"), ("ior = 1.5\n", "ior"), ("base = [2, 0, 0]\n", "base")]
        {
            let (line, msg) = error_line(&format!("{MINIMAL}{glossy}{extra}"));
            assert_eq!(line, Some(4), "{msg}");
            assert!(msg.contains(needle), "{msg}");
        }
        let (_, msg) = error_line(&format!(
            "{MINIMAL}[[material]]\nname = \"d\"\ntype = \"diffuse\"\nbase = [1, 1, 1]\n"
        ));
        assert!(msg.contains("base") && msg.contains("only glossy"), "{msg}");
    }
}
