//! The bytes behind a glTF: its buffers (a GLB's binary chunk, `data:` URIs, files beside it),
//! the accessors that read them and the images they hold. Read here, not by the `gltf` crate's
//! importer and readers, which trust the file: they panic on a stride below the element's
//! size, on float indices or on a view past its buffer's end, and allocate whatever count a
//! sparse accessor claims. Every offset, stride and count is checked against the bytes that
//! back it, and every allocation against the memory available, before anything is read.

use std::borrow::Cow;
use std::path::{Component, Path, PathBuf};

use gltf::json;
use json::accessor::{ComponentType, Type};

use crate::scene::image::{srgb_to_linear, Image};
use crate::scene::limits;

/// The name of the meshopt compression extension.
pub const MESHOPT: &str = "EXT_meshopt_compression";

/// The loaded buffers of a glTF, by index, and the files they came from.
pub struct Buffers<'a> {
    root: &'a json::Root,
    data: Vec<Cow<'a, [u8]>>,
    /// The views `EXT_meshopt_compression` compresses, decoded, by view index (with their
    /// stride).
    decoded: Vec<Option<(Vec<u8>, usize)>>,
    base: PathBuf,
    /// The external files read (buffers, then images as they are decoded).
    pub files: Vec<PathBuf>,
}

/// Where a URI points: its bytes (a `data:` URI) or a file inside the glTF's directory.
enum Resource {
    Data(Vec<u8>),
    File(PathBuf),
}

/// Whether `LIGHTSPLIT_ALLOW_OUTSIDE_FILES=1` lets a glTF read files outside its directory.
fn outside_allowed() -> bool {
    std::env::var_os("LIGHTSPLIT_ALLOW_OUTSIDE_FILES").is_some_and(|v| v == "1")
}

/// Resolves a URI of a glTF in `base`: a `data:` URI decoded, any other scheme (`file:`,
/// `http:`) refused, a relative path percent-decoded to bytes (not to UTF-8: `%FF` is the byte
/// 0xFF, not U+FFFD) and refused if it is absolute or leaves `base` (by `..` or a symbolic
/// link), unless `LIGHTSPLIT_ALLOW_OUTSIDE_FILES=1`. The path returned is the one to read.
fn resolve(base: &Path, uri: &str) -> Result<Resource, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (header, payload) = rest.split_once(',').ok_or("a data: URI without a comma")?;
        if !header.ends_with(";base64") {
            return Err("a data: URI that is not base64".into());
        }
        use base64::Engine;
        let bytes = base64::engine::general_purpose::STANDARD
            .decode(payload.trim_end())
            .map_err(|e| format!("a data: URI that is not valid base64 ({e})"))?;
        return Ok(Resource::Data(bytes));
    }
    let scheme = uri.split_once(':').is_some_and(|(s, _)| {
        !s.is_empty()
            && s.starts_with(|c: char| c.is_ascii_alphabetic())
            && s.chars().all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
    });
    if scheme {
        return Err("a URI with a scheme is not read (only relative paths and data: URIs are)".into());
    }
    use std::os::unix::ffi::OsStrExt;
    let decoded = urlencoding::decode_binary(uri.as_bytes());
    let relative = Path::new(std::ffi::OsStr::from_bytes(&decoded));
    let allowed = outside_allowed();
    if !allowed {
        let mut depth = 0i64;
        for c in relative.components() {
            match c {
                Component::Normal(_) => depth += 1,
                Component::CurDir => {}
                Component::ParentDir => depth -= 1,
                Component::RootDir | Component::Prefix(_) => depth = -1,
            }
            if depth < 0 {
                return Err(
                    "a path outside the glTF's directory (LIGHTSPLIT_ALLOW_OUTSIDE_FILES=1 allows it)".into(),
                );
            }
        }
    }
    let joined = base.join(relative);
    let real = joined.canonicalize().map_err(|e| format!("cannot read {}: {e}", joined.display()))?;
    if !allowed {
        let home = base.canonicalize().map_err(|e| format!("cannot read {}: {e}", base.display()))?;
        if !real.starts_with(&home) {
            return Err(format!(
                "{} leads outside the glTF's directory, to {} (LIGHTSPLIT_ALLOW_OUTSIDE_FILES=1 allows it)",
                joined.display(),
                real.display()
            ));
        }
    }
    limits::check_input_file(&real)?;
    Ok(Resource::File(real))
}

/// The bytes of a resolved URI, and the file read, if any.
fn read(resource: Resource) -> Result<(Vec<u8>, Option<PathBuf>), String> {
    match resource {
        Resource::Data(bytes) => Ok((bytes, None)),
        Resource::File(path) => {
            let bytes = std::fs::read(&path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
            Ok((bytes, Some(path)))
        }
    }
}

/// The bytes an element of `ty` components of `dims` takes.
fn element_size(ty: ComponentType, dims: Type) -> usize {
    component_size(ty) * dims.multiplicity()
}

fn component_size(ty: ComponentType) -> usize {
    match ty {
        ComponentType::I8 | ComponentType::U8 => 1,
        ComponentType::I16 | ComponentType::U16 => 2,
        ComponentType::U32 | ComponentType::F32 => 4,
    }
}

fn type_name(ty: ComponentType) -> &'static str {
    match ty {
        ComponentType::I8 => "BYTE",
        ComponentType::U8 => "UNSIGNED_BYTE",
        ComponentType::I16 => "SHORT",
        ComponentType::U16 => "UNSIGNED_SHORT",
        ComponentType::U32 => "UNSIGNED_INT",
        ComponentType::F32 => "FLOAT",
    }
}

/// Component `k` of little-endian `bytes` of type `ty`, as glTF reads it: a float as it is, an
/// integer as it is or, `normalized`, over its largest value (signed ones clamped at -1).
fn component(bytes: &[u8], ty: ComponentType, normalized: bool) -> f64 {
    let b = |i: usize| bytes[i];
    let (x, max) = match ty {
        ComponentType::F32 => return f32::from_le_bytes([b(0), b(1), b(2), b(3)]) as f64,
        ComponentType::I8 => (b(0) as i8 as f64, 127.0),
        ComponentType::U8 => (b(0) as f64, 255.0),
        ComponentType::I16 => (i16::from_le_bytes([b(0), b(1)]) as f64, 32767.0),
        ComponentType::U16 => (u16::from_le_bytes([b(0), b(1)]) as f64, 65535.0),
        ComponentType::U32 => (u32::from_le_bytes([b(0), b(1), b(2), b(3)]) as f64, 4294967295.0),
    };
    if normalized {
        (x / max).max(-1.0)
    } else {
        x
    }
}

/// An accessor's elements as read: where they start, how far apart, how many.
struct Layout<'b> {
    /// The bytes from the first element on (empty when the accessor has no buffer view: zeros).
    bytes: &'b [u8],
    stride: usize,
    count: usize,
    ty: ComponentType,
    dims: Type,
    normalized: bool,
}

impl<'a> Buffers<'a> {
    /// Loads every buffer of `root` (a GLB's binary chunk is `blob`), each at least as long as it
    /// says, from the files beside the glTF in `base` or its `data:` URIs.
    pub fn load(root: &'a json::Root, blob: Option<Vec<u8>>, base: &Path) -> Result<Buffers<'a>, String> {
        let mut blob = blob;
        let mut out = Buffers {
            root,
            data: Vec::new(),
            decoded: Vec::new(),
            base: base.to_path_buf(),
            files: Vec::new(),
        };
        for (i, b) in root.buffers.iter().enumerate() {
            let here = |e: String| match &b.uri {
                Some(uri) => format!("buffer {i} `{}`: {e}", uri),
                None => format!("buffer {i}: {e}"),
            };
            // A meshopt file's fallback buffer need hold nothing: its views are decoded from
            // another buffer.
            let fallback = b
                .extensions
                .as_ref()
                .and_then(|e| e.others.get(MESHOPT))
                .and_then(|m| m.get("fallback"))
                .and_then(|f| f.as_bool())
                .unwrap_or(false);
            if fallback && b.uri.is_none() {
                out.data.push(Cow::Owned(Vec::new()));
                continue;
            }
            let bytes = match &b.uri {
                Some(uri) => {
                    let (bytes, file) = resolve(base, uri).and_then(read).map_err(here)?;
                    out.files.extend(file);
                    bytes
                }
                None => blob.take().ok_or_else(|| here("no URI and no GLB binary chunk".into()))?,
            };
            let length = b.byte_length.0;
            if (bytes.len() as u64) < length {
                return Err(here(format!("{} bytes, fewer than its byteLength {length}", bytes.len())));
            }
            out.data.push(Cow::Owned(bytes));
        }
        out.decoded = (0..root.buffer_views.len()).map(|v| out.meshopt_view(v)).collect::<Result<_, _>>()?;
        Ok(out)
    }

    /// Buffer view `v` decoded, when `EXT_meshopt_compression` compresses it: its compressed
    /// bytes (in the extension's buffer) through the extension's mode and filter, by the
    /// `meshoptimizer-rs` crate, into `count` elements of `byteStride` bytes.
    fn meshopt_view(&self, v: usize) -> Result<Option<(Vec<u8>, usize)>, String> {
        let Some(view) = self.root.buffer_views.get(v) else { return Ok(None) };
        let Some(ext) = view.extensions.as_ref().and_then(|e| e.others.get(MESHOPT)) else { return Ok(None) };
        let bad = |what: &str| format!("buffer view {v}: {MESHOPT}: {what}");
        let number = |key: &str| ext.get(key).and_then(|x| x.as_u64());
        let (Some(buffer), Some(length), Some(stride), Some(count)) =
            (number("buffer"), number("byteLength"), number("byteStride"), number("count"))
        else {
            return Err(bad("it needs `buffer`, `byteLength`, `byteStride` and `count`"));
        };
        let offset = number("byteOffset").unwrap_or(0);
        let source = self.data.get(buffer as usize).ok_or_else(|| bad(&format!("no buffer {buffer}")))?;
        let end = offset.checked_add(length).filter(|&e| e <= source.len() as u64).ok_or_else(|| {
            bad(&format!(
                "{length} bytes at {offset} run past the end of buffer {buffer} ({} bytes)",
                source.len()
            ))
        })?;
        if count > limits::MAX_ELEMENTS || stride > 256 {
            return Err(bad(&format!(
                "{count} elements of {stride} bytes, over the {} elements of at most 256 bytes it may hold",
                limits::MAX_ELEMENTS
            )));
        }
        use meshoptimizer_rs::codec::{Filter, Mode};
        let mode = Mode::parse(ext.get("mode").and_then(|m| m.as_str()).unwrap_or(""))
            .map_err(|_| bad("its `mode` is not ATTRIBUTES, TRIANGLES or INDICES"))?;
        let filter = match ext.get("filter").and_then(|f| f.as_str()).unwrap_or("NONE") {
            "NONE" => Filter::None,
            "OCTAHEDRAL" => Filter::Octahedral,
            "QUATERNION" => Filter::Quaternion,
            "EXPONENTIAL" => Filter::Exponential,
            other => return Err(bad(&format!("a filter `{other}` it does not know"))),
        };
        let compressed = &source[offset as usize..end as usize];
        let decoded = meshoptimizer_rs::codec::decode_buffer_view(
            mode,
            filter,
            count as usize,
            stride as usize,
            compressed,
            &mut meshoptimizer_rs::Workspace::default(),
        )
        .map_err(|e| bad(&format!("cannot decode it: {e:?}")))?;
        Ok(Some((decoded, stride as usize)))
    }

    /// The bytes of buffer view `v`, checked to lie inside its buffer.
    fn view(&self, v: usize) -> Result<(&[u8], Option<usize>), String> {
        if let Some(Some((bytes, stride))) = self.decoded.get(v) {
            return Ok((bytes, Some(*stride)));
        }
        let view = self.root.buffer_views.get(v).ok_or_else(|| format!("no buffer view {v}"))?;
        let buffer =
            self.data.get(view.buffer.value()).ok_or_else(|| format!("buffer view {v}: no buffer"))?;
        let offset = view.byte_offset.map_or(0, |o| o.0);
        let end = offset.checked_add(view.byte_length.0);
        match end {
            Some(end) if end <= buffer.len() as u64 => {
                Ok((&buffer[offset as usize..end as usize], view.byte_stride.map(|s| s.0).filter(|&s| s > 0)))
            }
            _ => Err(format!(
                "buffer view {v} (offset {offset}, {} bytes) runs past the end of buffer {} ({} bytes)",
                view.byte_length.0,
                view.buffer.value(),
                buffer.len()
            )),
        }
    }

    /// The layout of `count` elements of `element` bytes at `offset` in view `v`, or an error
    /// if the view cannot hold them or its stride is below the element's size.
    fn elements(&self, v: usize, offset: u64, count: u64, element: usize) -> Result<(&[u8], usize), String> {
        let (bytes, stride) = self.view(v)?;
        let stride = stride.unwrap_or(element);
        if stride < element {
            return Err(format!(
                "buffer view {v}: a byteStride of {stride}, below the {element}-byte element"
            ));
        }
        if count == 0 {
            return Ok((&[], stride));
        }
        let need = (count - 1)
            .checked_mul(stride as u64)
            .and_then(|n| n.checked_add(element as u64))
            .and_then(|n| n.checked_add(offset));
        match need {
            Some(need) if need <= bytes.len() as u64 => Ok((&bytes[offset as usize..need as usize], stride)),
            _ => Err(format!(
                "{count} elements of {element} bytes every {stride} from offset {offset} do not fit in buffer view {v} ({} bytes)",
                bytes.len()
            )),
        }
    }

    /// The layout of accessor `a`, its count checked against the bytes behind it.
    fn layout(&self, a: usize) -> Result<Layout<'_>, String> {
        let acc = self.root.accessors.get(a).ok_or_else(|| format!("no accessor {a}"))?;
        let here = |e: String| format!("accessor {a}: {e}");
        let ty = match acc.component_type {
            json::validation::Checked::Valid(json::accessor::GenericComponentType(t)) => t,
            _ => return Err(here("an unknown componentType".into())),
        };
        let dims = match acc.type_ {
            json::validation::Checked::Valid(t) => t,
            _ => return Err(here("an unknown type".into())),
        };
        let count = acc.count.0;
        if count > limits::MAX_ELEMENTS {
            return Err(here(format!("a count of {count}, over the {} read at most", limits::MAX_ELEMENTS)));
        }
        let element = element_size(ty, dims);
        let (bytes, stride) = match acc.buffer_view {
            Some(v) => {
                self.elements(v.value(), acc.byte_offset.map_or(0, |o| o.0), count, element).map_err(here)?
            }
            // Zeros, but for sparse values: a morph target's displacements, as many as the
            // vertices some other accessor holds in a buffer. More elements than all the
            // buffers could hold are a count no data backs (1e12 of them in a 700-byte file).
            None => {
                let held: u64 = self.data.iter().map(|d| d.len() as u64).sum();
                if count.saturating_mul(element as u64) > held.max(1 << 16) {
                    return Err(here(format!(
                        "{count} elements of {element} bytes and no buffer view: more than the file's {held} bytes of buffers hold"
                    )));
                }
                (&[][..], element)
            }
        };
        Ok(Layout { bytes, stride, count: count as usize, ty, dims, normalized: acc.normalized })
    }

    /// Whether the file uses `KHR_mesh_quantization`: integer positions, normals, tangents and
    /// texture coordinates, normalized or not (its nodes' transforms undo the quantization).
    pub fn quantized(&self) -> bool {
        self.root.extensions_used.iter().any(|e| e == "KHR_mesh_quantization")
    }

    /// The elements of accessor `a`, of `dims` components of one of `types`, as floats, `dims`
    /// a vertex (sparse values applied). `what` names the data in messages.
    pub fn floats(
        &self,
        a: usize,
        what: &str,
        dims: Type,
        types: &[ComponentType],
    ) -> Result<Vec<f32>, String> {
        let layout = self.layout(a)?;
        let here = |e: String| format!("accessor {a} ({what}): {e}");
        if layout.dims != dims || !types.contains(&layout.ty) {
            let names: Vec<&str> = types.iter().map(|&t| type_name(t)).collect();
            let quantized = match layout.ty == ComponentType::F32 || self.quantized() {
                true => "",
                false => " (the file does not use KHR_mesh_quantization, which allows integers here)",
            };
            return Err(here(format!(
                "{:?} of {}, where {:?} of {} is read{quantized}",
                layout.dims,
                type_name(layout.ty),
                dims,
                names.join(" or ")
            )));
        }
        if layout.ty != ComponentType::F32 && !layout.normalized && !self.quantized() {
            return Err(here(format!(
                "{} that is not normalized (the file does not use KHR_mesh_quantization, which allows it)",
                type_name(layout.ty)
            )));
        }
        let n = dims.multiplicity();
        let total = layout.count as u64 * n as u64;
        limits::check_memory(total * 4, &format!("accessor {a} ({what})"))?;
        let size = component_size(layout.ty);
        let mut out = vec![0.0f32; total as usize];
        if !layout.bytes.is_empty() {
            for (i, e) in out.chunks_exact_mut(n).enumerate() {
                let at = &layout.bytes[i * layout.stride..];
                for (k, x) in e.iter_mut().enumerate() {
                    *x = component(&at[k * size..], layout.ty, layout.normalized) as f32;
                }
            }
        }
        self.sparse(a, layout.count, |i, at| {
            for (k, x) in out[i * n..(i + 1) * n].iter_mut().enumerate() {
                *x = component(&at[k * size..], layout.ty, layout.normalized) as f32;
            }
        })
        .map_err(here)?;
        Ok(out)
    }

    /// The indices of accessor `a` (scalars of unsigned bytes, shorts or ints).
    pub fn indices(&self, a: usize) -> Result<Vec<u32>, String> {
        let layout = self.layout(a)?;
        let here = |e: String| format!("accessor {a} (indices): {e}");
        let unsigned = [ComponentType::U8, ComponentType::U16, ComponentType::U32];
        if layout.dims != Type::Scalar || !unsigned.contains(&layout.ty) {
            return Err(here(format!(
                "{:?} of {}, where indices are scalars of UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT",
                layout.dims,
                type_name(layout.ty)
            )));
        }
        limits::check_memory(layout.count as u64 * 4, &format!("accessor {a} (indices)"))?;
        let index = |at: &[u8]| component(at, layout.ty, false) as u32;
        let mut out = vec![0u32; layout.count];
        if !layout.bytes.is_empty() {
            for (i, x) in out.iter_mut().enumerate() {
                *x = index(&layout.bytes[i * layout.stride..]);
            }
        }
        self.sparse(a, layout.count, |i, at| out[i] = index(at)).map_err(here)?;
        Ok(out)
    }

    /// Calls `set(i, bytes)` for each sparse value of accessor `a` (of `count` elements), its
    /// indices and values checked against their views and the count.
    fn sparse(&self, a: usize, count: usize, mut set: impl FnMut(usize, &[u8])) -> Result<(), String> {
        let Some(acc) = self.root.accessors.get(a) else { return Ok(()) };
        let Some(sparse) = &acc.sparse else { return Ok(()) };
        let n = sparse.count.0;
        if n > count as u64 {
            return Err(format!("{n} sparse values for {count} elements"));
        }
        let index_type = match sparse.indices.component_type {
            json::validation::Checked::Valid(json::accessor::IndexComponentType(t))
                if matches!(t, ComponentType::U8 | ComponentType::U16 | ComponentType::U32) =>
            {
                t
            }
            _ => return Err("sparse indices that are not unsigned integers".into()),
        };
        let (ty, dims) = match (acc.component_type, acc.type_) {
            (
                json::validation::Checked::Valid(json::accessor::GenericComponentType(t)),
                json::validation::Checked::Valid(d),
            ) => (t, d),
            _ => return Err("an unknown componentType or type".into()),
        };
        let index_size = component_size(index_type);
        let (indices, index_stride) =
            self.elements(sparse.indices.buffer_view.value(), sparse.indices.byte_offset.0, n, index_size)?;
        let element = element_size(ty, dims);
        let (values, value_stride) =
            self.elements(sparse.values.buffer_view.value(), sparse.values.byte_offset.0, n, element)?;
        for j in 0..n as usize {
            let i = component(&indices[j * index_stride..], index_type, false) as usize;
            if i >= count {
                return Err(format!("sparse index {i} out of range ({count} elements)"));
            }
            set(i, &values[j * value_stride..]);
        }
        Ok(())
    }

    /// The encoded bytes of image `i` (a PNG or JPEG), from its buffer view or URI.
    fn image_bytes(&mut self, i: usize) -> Result<Cow<'_, [u8]>, String> {
        let image = self.root.images.get(i).ok_or_else(|| format!("no image {i}"))?;
        match (&image.buffer_view, &image.uri) {
            (Some(v), _) => Ok(Cow::Borrowed(self.view(v.value())?.0)),
            (None, Some(uri)) => {
                let (bytes, file) =
                    resolve(&self.base, uri).and_then(read).map_err(|e| format!("`{}`: {e}", uri))?;
                self.files.extend(file);
                Ok(Cow::Owned(bytes))
            }
            (None, None) => Err("neither a buffer view nor a URI".into()),
        }
    }

    /// Decodes image `i` to linear RGB (from sRGB when `srgb`), its declared size checked against
    /// the memory available before its pixels are decoded.
    pub fn image(&mut self, i: usize, srgb: bool) -> Result<Image, String> {
        let bytes = self.image_bytes(i)?;
        decode(&bytes, srgb)
    }

    /// Image `i`'s alpha channel, as a grey image.
    pub fn image_alpha(&mut self, i: usize) -> Result<Image, String> {
        let bytes = self.image_bytes(i)?;
        decode_alpha(&bytes)
    }
}

/// Decodes a PNG or JPEG (the format from its bytes, not its stated MIME type) to linear RGB,
/// 8- and 16-bit values from sRGB when `srgb`, float ones as they are.
pub fn decode(bytes: &[u8], srgb: bool) -> Result<Image, String> {
    let (width, height, decoded) = read_image(bytes)?;
    let curve = |x: f32| if srgb { srgb_to_linear(x) } else { x };
    let pixels: Vec<glam::Vec3> = match decoded.color().bytes_per_pixel() / decoded.color().channel_count() {
        1 => decoded
            .into_rgb8()
            .pixels()
            .map(|p| glam::Vec3::from(p.0.map(|c| curve(c as f32 / 255.0))))
            .collect(),
        2 => decoded
            .into_rgb16()
            .pixels()
            .map(|p| glam::Vec3::from(p.0.map(|c| curve(c as f32 / 65535.0))))
            .collect(),
        _ => decoded.into_rgb32f().pixels().map(|p| glam::Vec3::from(p.0)).collect(),
    };
    finite(Image { width, height, pixels })
}

/// Decodes a PNG or JPEG's alpha channel (1 where it has none), linear, in all three channels.
pub fn decode_alpha(bytes: &[u8]) -> Result<Image, String> {
    let (width, height, decoded) = read_image(bytes)?;
    let pixels = decoded.into_rgba32f().pixels().map(|p| glam::Vec3::splat(p.0[3])).collect();
    finite(Image { width, height, pixels })
}

fn finite(image: Image) -> Result<Image, String> {
    if image.pixels.iter().any(|p| !p.is_finite()) {
        return Err("a pixel is NaN or infinite".into());
    }
    Ok(image)
}

/// An image's size and decoded pixels, its size and memory checked first.
fn read_image(bytes: &[u8]) -> Result<(u32, u32, image::DynamicImage), String> {
    use image::{ImageDecoder, ImageReader};
    let reader =
        || ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format().map_err(|e| e.to_string());
    let (width, height) = reader()?.into_dimensions().map_err(|e| e.to_string())?;
    let pixels = width as u64 * height as u64;
    if pixels == 0 || width > limits::MAX_SIZE || height > limits::MAX_SIZE {
        return Err(format!("a size of {width}x{height} (each side 1 to {} pixels)", limits::MAX_SIZE));
    }
    let mut decoder = reader()?.into_decoder().map_err(|e| e.to_string())?;
    // The decoder's buffer and the linear image (16 bytes a pixel at most, as RGBA f32).
    let bytes_per_pixel = decoder.color_type().bytes_per_pixel() as u64;
    limits::check_memory(pixels * (bytes_per_pixel + 16), &format!("a {width}x{height} image"))?;
    // The size is checked: the decoder's own limit (512 MiB) would refuse an 8K 16-bit map.
    let mut limits = image::Limits::no_limits();
    limits.max_image_width = Some(width);
    limits.max_image_height = Some(height);
    decoder.set_limits(limits).map_err(|e| e.to_string())?;
    let decoded = image::DynamicImage::from_decoder(decoder).map_err(|e| e.to_string())?;
    Ok((width, height, decoded))
}
