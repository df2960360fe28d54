//! `[[texture]]`: textures by name. Constant, checker and image textures, and the solid noise
//! patterns (perlin, fbm, turbulence, marble); an image is read here, relative to the scene file.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use glam::{Vec2, Vec3};
use serde::Deserialize;

use super::typed::{Table, Typed};
use super::{v3, Ctx, Exact, Wide, F, V3};
use crate::scene::image;
use crate::scene::texture::{Pattern, Texture};
use crate::scene::SceneError;

/// The keys every texture takes.
#[derive(Deserialize)]
pub(super) struct TextureCommon {
    name: String,
}

/// A texture's type and its own keys.
#[derive(Deserialize)]
#[serde(rename_all = "lowercase")]
pub(super) enum TextureKind {
    Constant(Constant),
    Checker(Checker),
    Image(ImageMap),
    Perlin(Noise),
    Fbm(Noise),
    Turbulence(Noise),
    Marble(Noise),
}

impl Typed for TextureKind {
    type Common = TextureCommon;
    const SECTION: &'static str = "texture";
}

/// One colour everywhere.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Constant {
    color: V3,
}

/// Cubes alternating between two colours.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Checker {
    color: Option<V3>,
    color2: Option<V3>,
    size: Option<F>,
}

/// An image file over the unit square of (u, v).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ImageMap {
    file: String,
    repeat: Option<Exact<2>>,
}

/// A solid noise pattern blending two colours.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Noise {
    color: Option<V3>,
    color2: Option<V3>,
    frequency: Option<F>,
    octaves: Option<u32>,
    seed: Option<u32>,
}

impl TextureKind {
    /// The file an image texture reads, as written (relative to the scene file).
    pub(super) fn file(&self) -> Option<&str> {
        match self {
            TextureKind::Image(i) => Some(&i.file),
            _ => None,
        }
    }
}

/// The textures of a file, and their indices by name.
pub(super) fn textures(
    ctx: &Ctx,
    dir: &Path,
    tables: &[Table<TextureKind>],
) -> Result<(Vec<Texture>, HashMap<String, u32>), SceneError> {
    let (mut textures, mut ids) = (Vec::new(), HashMap::new());
    for t in tables {
        let name = &t.common.name;
        if ids.contains_key(name) {
            return ctx.err(t.span.clone(), format!("texture `{name}` is defined twice"));
        }
        ids.insert(name.clone(), textures.len() as u32);
        textures.push(texture(ctx, dir, t)?);
    }
    Ok((textures, ids))
}

/// An image read as a colour (a texture file, an `.mtl`'s `map_Kd`): refused if a pixel is NaN
/// or infinite (with the count), its values clamped to [0, 1] as a material's colour (a value of
/// 100 would multiply the light it reflects).
pub(super) fn colour_image(path: &Path) -> Result<Arc<crate::scene::image::Image>, String> {
    checked_image(path, image::read)
}

/// An image read as data (8-bit values without the sRGB curve: a height map), checked and
/// clamped as [`colour_image`] does.
pub(super) fn data_image(path: &Path) -> Result<Arc<crate::scene::image::Image>, String> {
    checked_image(path, image::read_linear)
}

/// An image read as coverage (its alpha, else its first channel: an OBJ's `map_d`), checked
/// and clamped as [`colour_image`] does.
pub(super) fn coverage_image(path: &Path) -> Result<Arc<crate::scene::image::Image>, String> {
    checked_image(path, image::read_coverage)
}

fn checked_image(
    path: &Path,
    read: fn(&Path) -> Result<crate::scene::image::Image, String>,
) -> Result<Arc<crate::scene::image::Image>, String> {
    let mut image = crate::scene::limits::check_input_file(path).and_then(|()| read(path))?;
    let bad = image.pixels.iter().filter(|p| !p.is_finite()).count();
    if bad > 0 {
        return Err(format!("{bad} of its {} pixels are NaN or infinite", image.pixels.len()));
    }
    image.pixels.iter_mut().for_each(|p| *p = p.clamp(Vec3::ZERO, Vec3::ONE));
    Ok(Arc::new(image))
}

/// A texture, checked: colours in [0, 1] as a material's are, sizes and frequencies positive;
/// an image read, refused if a pixel is NaN or infinite, its values clamped to [0, 1].
fn texture(ctx: &Ctx, dir: &Path, t: &Table<TextureKind>) -> Result<Texture, SceneError> {
    let span = t.span.clone();
    // The two colours of a pattern: black to white unless given.
    let colours = |a: Option<V3>, b: Option<V3>| {
        let (a, b) = (v3(a.unwrap_or(Exact([Wide(0.0); 3]))), v3(b.unwrap_or(Exact([Wide(1.0); 3]))));
        if a.min_element() < 0.0 || b.min_element() < 0.0 || a.max_element() > 1.0 || b.max_element() > 1.0 {
            ctx.err(span.clone(), "texture colours must lie in [0, 1], as a material's colour")
        } else {
            Ok((a, b))
        }
    };
    let (pattern, noise) = match &t.of_type {
        TextureKind::Constant(c) => return Ok(Texture::Constant(colours(Some(c.color), None)?.0)),
        TextureKind::Checker(c) => {
            let (a, b) = colours(c.color, c.color2)?;
            let size = c.size.map_or(1.0, |s| s.0);
            if size <= 0.0 {
                return ctx.err(span, "a checker's `size` must be positive");
            }
            return Ok(Texture::Checker { a, b, size });
        }
        TextureKind::Image(i) => {
            let image = colour_image(&dir.join(&i.file))
                .or_else(|e| ctx.err(span.clone(), format!("texture `{}`: {e}", t.common.name)))?;
            let repeat = i.repeat.map_or(Vec2::ONE, |Exact([u, v])| Vec2::new(u.0 as f32, v.0 as f32));
            if repeat.min_element() <= 0.0 {
                return ctx.err(span, "`repeat` must be positive");
            }
            return Ok(Texture::image(image, repeat, None, Default::default()));
        }
        TextureKind::Perlin(n) => (Pattern::Perlin, n),
        TextureKind::Fbm(n) => (Pattern::Fbm, n),
        TextureKind::Turbulence(n) => (Pattern::Turbulence, n),
        TextureKind::Marble(n) => (Pattern::Marble, n),
    };
    let (a, b) = colours(noise.color, noise.color2)?;
    let frequency = noise.frequency.map_or(1.0, |f| f.0);
    if frequency <= 0.0 {
        return ctx.err(span, "`frequency` must be positive");
    }
    let octaves = noise.octaves.unwrap_or(6);
    if !(1..=16).contains(&octaves) {
        return ctx.err(span, "`octaves` must lie between 1 and 16");
    }
    Ok(Texture::Noise { pattern, a, b, frequency, octaves, seed: noise.seed.unwrap_or(0) })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::file::parse;
    use crate::scene::file::tests::{error_line, parse_str, MINIMAL};
    use crate::scene::Maps;

    #[test]
    fn textures_and_their_errors() {
        let marble = "[[texture]]\nname = \"m\"\ntype = \"marble\"\nfrequency = 2\n";
        let mat = "[[material]]\nname = \"x\"\ntype = \"diffuse\"\n";
        let s = parse_str(&format!("{MINIMAL}{marble}{mat}texture = \"m\"\nbump = \"m\"\n")).expect("parses");
        assert!(matches!(s.textures[0], Texture::Noise { pattern: Pattern::Marble, frequency: 2.0, .. }));
        assert_eq!(*s.maps(0), Maps { color: Some(0), bump: Some((0, 0.02)), ..Maps::NONE });
        assert_eq!(*s.maps(7), Maps::NONE);
        assert_eq!(Maps::NONE, Maps::default());
        let image = "[[texture]]\nname = \"i\"\ntype = \"image\"\nfile = \"nowhere.png\"\n";
        for (text, needle, line) in [
            (format!("{MINIMAL}{mat}texture = \"nope\"\n"), "nope", 4),
            (format!("{MINIMAL}{image}"), "nowhere.png", 4),
            (format!("{MINIMAL}{marble}octaves = 40\n"), "octaves", 4),
            (format!("{MINIMAL}{marble}file = \"a.png\"\n"), "file", 4),
            (
                format!("{MINIMAL}{marble}[[material]]\nname = \"g\"\ntype = \"mirror\"\ntexture = \"m\"\n"),
                "only diffuse",
                8,
            ),
            (format!("{MINIMAL}{mat}bump_height = 1\n"), "bump", 4),
        ] {
            let (l, msg) = error_line(&text);
            assert_eq!(l, Some(line), "{msg}");
            assert!(msg.contains(needle), "{needle}: {msg}");
        }
        // An image texture cannot be a bump map (it has no gradient in space).
        let dir = tempfile::tempdir().expect("tempdir");
        ::image::RgbImage::new(2, 2).save(dir.path().join("i.png")).expect("png");
        let text = format!("{MINIMAL}{}{mat}bump = \"i\"\n", image.replace("nowhere.png", "i.png"));
        let e = parse(&dir.path().join("s.toml"), &text).expect_err("must fail");
        assert!(e.message.contains("solid"), "{}", e.message);
    }
}
