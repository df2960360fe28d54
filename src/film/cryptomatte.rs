//! Cryptomatte ID mattes (Friedman & Jones 2015, specification 1.2.0).
//!
//! # What this produces
//! For one Cryptomatte *type* (for example `CryptoObject`, `CryptoMaterial`, `CryptoAsset`)
//! the renderer writes:
//!
//! * **Rank layers** `<type>00`, `<type>01`, … with channels `R G B A`. Layer `i` holds two
//!   ranks: `R` = id of rank `2i`, `G` = its coverage, `B` = id of rank `2i+1`, `A` = its
//!   coverage. Six ranks (three layers) is the specification's suggested default.
//!   [`layer_names`] / [`channel_names`] give the names and [`Coverage::write_layers`] the pixels.
//! * **Four string header attributes** from [`header`]: `cryptomatte/<key>/name` (the type
//!   name), `…/hash` = `MurmurHash3_32`, `…/conversion` = `uint32_to_float32` and `…/manifest`,
//!   a JSON object mapping every name to its id as 8 lower-case hex digits.
//!
//! An *id* is MurmurHash3_x86_32 (seed 0) of the name's UTF-8 bytes, turned into a float by
//! copying the bits and, when the exponent is 0 or 255, toggling the lowest exponent bit, so the
//! float is never zero, denormal, infinite or NaN ([`hash_to_float`]). A pixel's coverage of an
//! id is the summed filter weight of the samples that hit it divided by the pixel's total weight
//! (samples that hit nothing count in the total; the specification records them as id 0).
//!
//! # How a compositor reads it
//! The decoder (Nuke's or Fusion's Cryptomatte node, Blender, …) finds the type by the header's
//! `name`, collects the layers `<name>NN`, and for a set of picked names builds
//! `matte = Σ over all (id, coverage) pairs of coverage where id ∈ {hash_to_float(name_hash(n))}`.
//! The manifest only maps ids back to names for the picker; mattes never depend on it.
//! The id channels therefore must be stored bit-exact: 32-bit FLOAT channels, lossless
//! compression (none, RLE, ZIPS, ZIP, PIZ), never HALF, PXR24, B44 or DWA.
//!
//! # Per-pixel accumulation
//! [`Coverage`] sums sample weights per id in 32.32 fixed point, so accumulation and merging are
//! exact and order-independent: adding the samples in any order, or merging separately rendered
//! tiles/parts in any order and any grouping, gives a bit-identical result, as long as no pixel
//! sees more than [`CAP`] distinct ids (see [`Coverage`] for what happens beyond that).

use std::cmp::Ordering;
use std::fmt::Write as _;

/// The value of the `hash` header attribute.
pub const HASH: &str = "MurmurHash3_32";
/// The value of the `conversion` header attribute.
pub const CONVERSION: &str = "uint32_to_float32";
/// The specification's suggested number of ranks (three layers).
pub const DEFAULT_RANKS: usize = 6;
/// Channel names of every rank layer, in id/coverage/id/coverage order.
pub const CHANNELS: [&str; 4] = ["R", "G", "B", "A"];
/// Most distinct ids one [`Coverage`] keeps per pixel.
pub const CAP: usize = 16;
/// Largest number of bytes [`Coverage::to_bytes`] appends for one pixel.
pub const MAX_ENCODED_LEN: usize = 1 + 8 + 8 + CAP * 12;

// The serialised length field has 5 bits.
const _: () = assert!(CAP <= 31);

/// MurmurHash3_x86_32 of `bytes` with `seed`, as in Austin Appleby's reference (little-endian).
pub fn murmur3_32(bytes: &[u8], seed: u32) -> u32 {
    fn scramble(k: u32) -> u32 {
        k.wrapping_mul(0xcc9e_2d51).rotate_left(15).wrapping_mul(0x1b87_3593)
    }
    let mut h = seed;
    let mut blocks = bytes.chunks_exact(4);
    for b in &mut blocks {
        h ^= scramble(u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
        h = h.rotate_left(13).wrapping_mul(5).wrapping_add(0xe654_6b64);
    }
    let tail = blocks.remainder();
    if !tail.is_empty() {
        let k = tail.iter().enumerate().fold(0u32, |k, (i, &b)| k | u32::from(b) << (8 * i));
        h ^= scramble(k);
    }
    // The reference takes the length as a 32-bit int; longer inputs wrap the same way.
    h ^= bytes.len() as u32;
    h ^= h >> 16;
    h = h.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 13;
    h = h.wrapping_mul(0xc2b2_ae35);
    h ^ (h >> 16)
}

/// The specification's hash of a name: MurmurHash3_x86_32 with seed 0 of its UTF-8 bytes.
pub fn name_hash(name: &str) -> u32 {
    murmur3_32(name.as_bytes(), 0)
}

/// The `uint32_to_float32` conversion: the hash's bits, with exponent 0 or 255 toggled to 1 or 254.
pub fn hash_to_float(h: u32) -> f32 {
    let exponent = (h >> 23) & 0xff;
    f32::from_bits(if exponent == 0 || exponent == 0xff { h ^ (1 << 23) } else { h })
}

/// The id of a name as stored in pixels: the bits of `hash_to_float(name_hash(name))`.
pub fn name_id(name: &str) -> u32 {
    hash_to_float(name_hash(name)).to_bits()
}

/// An id as the manifest writes it: 8 lower-case hex digits of the float's bits.
pub fn id_hex(id: u32) -> String {
    format!("{id:08x}")
}

/// The 7-character metadata key of a type: the first 7 hex digits of `id_hex(name_id(type_name))`.
pub fn layer_key(type_name: &str) -> String {
    format!("{:07x}", name_id(type_name) >> 4)
}

/// Whether a type name is safe in EXR layer names and compositors: `[A-Za-z_][A-Za-z0-9_-]*`.
pub fn is_portable_type_name(type_name: &str) -> bool {
    let mut chars = type_name.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

/// The manifest JSON `{"name":"id hex",…}`: names deduplicated, sorted by UTF-8 bytes, escaped.
///
/// Escaping follows the reference Arnold encoder (`"`, `\` and `/` get a backslash), plus JSON's
/// escapes for control characters; everything else is written as raw UTF-8.
pub fn manifest(names: &[&str]) -> String {
    let mut sorted = names.to_vec();
    sorted.sort_unstable();
    sorted.dedup();
    let mut out = String::with_capacity(2 + sorted.iter().map(|n| n.len() + 14).sum::<usize>());
    out.push('{');
    for (i, name) in sorted.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        out.push('"');
        for c in name.chars() {
            match c {
                '"' => out.push_str("\\\""),
                '\\' => out.push_str("\\\\"),
                '/' => out.push_str("\\/"),
                '\n' => out.push_str("\\n"),
                '\r' => out.push_str("\\r"),
                '\t' => out.push_str("\\t"),
                '\u{8}' => out.push_str("\\b"),
                '\u{c}' => out.push_str("\\f"),
                c if u32::from(c) < 0x20 => {
                    let _ = write!(out, "\\u{:04x}", u32::from(c));
                }
                c => out.push(c),
            }
        }
        let _ = write!(out, "\":\"{:08x}\"", name_id(name));
    }
    out.push('}');
    out
}

fn attributes(type_name: &str, last: (&str, String)) -> Vec<(String, String)> {
    let prefix = format!("cryptomatte/{}/", layer_key(type_name));
    vec![
        (format!("{prefix}name"), type_name.to_string()),
        (format!("{prefix}hash"), HASH.to_string()),
        (format!("{prefix}conversion"), CONVERSION.to_string()),
        (format!("{prefix}{}", last.0), last.1),
    ]
}

/// The four string header attributes (name, hash, conversion, manifest) of one type.
pub fn header(type_name: &str, names: &[&str]) -> Vec<(String, String)> {
    attributes(type_name, ("manifest", manifest(names)))
}

/// Like [`header`] but pointing at a sidecar manifest file (`manif_file`, a `.json` path
/// relative to the image's directory, not starting with `./` or `../`) holding [`manifest`].
pub fn sidecar_header(type_name: &str, manif_file: &str) -> Vec<(String, String)> {
    attributes(type_name, ("manif_file", manif_file.to_string()))
}

/// The rank layer names for `ranks` ranks: `<type>00`, `<type>01`, … (two ranks per layer).
/// Keep `ranks` ≤ 200: decoders sort the names, and `<type>100` would sort before `<type>11`.
pub fn layer_names(type_name: &str, ranks: usize) -> Vec<String> {
    (0..ranks.div_ceil(2)).map(|i| format!("{type_name}{i:02}")).collect()
}

/// Full channel names, `<type>00.R`, `<type>00.G`, … for `ranks` ranks.
pub fn channel_names(type_name: &str, ranks: usize) -> Vec<String> {
    layer_names(type_name, ranks)
        .iter()
        .flat_map(|layer| CHANNELS.iter().map(move |c| format!("{layer}.{c}")))
        .collect()
}

/// Ranking order: heavier first, equal weights by id bits ascending.
fn rank_order(a: &(u32, u64), b: &(u32, u64)) -> Ordering {
    b.1.cmp(&a.1).then(a.0.cmp(&b.0))
}

/// A sample weight in 32.32 fixed point; NaN, infinite, negative and tiny weights give 0.
fn quantize(weight: f32) -> u64 {
    if weight.is_finite() && weight > 0.0 {
        // `as` saturates, so weights of 2^32 and more clamp to u64::MAX.
        (f64::from(weight) * 4_294_967_296.0).round() as u64
    } else {
        0
    }
}

/// One pixel's coverage by id: up to [`CAP`] distinct ids with their summed sample weights.
///
/// Weights are summed in 32.32 fixed point (resolution 2⁻³²; each sum saturates at 2³²), so
/// every sum is exact: adding samples in any order and merging parts in any order or grouping
/// yields `==` states and bit-identical ranks. Use non-negative filter kernels; NaN, infinite
/// and negative weights are ignored.
///
/// **Overflow policy.** When a pixel would hold more than `CAP` distinct ids, the `CAP`
/// heaviest (ties: smaller id bits) are kept and the weight of the others moves to a `dropped`
/// counter, so coverages still divide by the pixel's true total weight and the ranks never sum
/// to more than the covered fraction. An id evicted early and hit again later restarts from its
/// later weight, so which ids survive (not the total) can then depend on sample and merge order.
/// Without overflow, state and output are fully order-independent.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Coverage {
    ids: [u32; CAP],
    weights: [u64; CAP],
    len: u8,
    none: u64,
    dropped: u64,
}

impl Coverage {
    /// An empty pixel.
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of distinct ids kept.
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// Whether no id is kept.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Adds a sample of `id` (use [`name_id`]; a raw [`name_hash`] maps to the same entry, and
    /// id 0 means "no object", like [`add_none`](Self::add_none)) with its filter `weight`.
    pub fn add(&mut self, id: u32, weight: f32) {
        let w = quantize(weight);
        if w == 0 {
            return;
        }
        if id == 0 {
            self.none = self.none.saturating_add(w);
            return;
        }
        let id = hash_to_float(id).to_bits();
        let len = self.len();
        match self.ids[..len].binary_search(&id) {
            Ok(i) => self.weights[i] = self.weights[i].saturating_add(w),
            Err(pos) if len < CAP => {
                self.ids.copy_within(pos..len, pos + 1);
                self.weights.copy_within(pos..len, pos + 1);
                self.ids[pos] = id;
                self.weights[pos] = w;
                self.len += 1;
            }
            Err(_) => {
                let mut one = Coverage::new();
                (one.ids[0], one.weights[0], one.len) = (id, w, 1);
                self.merge(&one);
            }
        }
    }

    /// Adds the weight of a sample that hit nothing (it counts in the pixel's total weight).
    pub fn add_none(&mut self, weight: f32) {
        self.none = self.none.saturating_add(quantize(weight));
    }

    /// Merges another part of the same pixel (a tile, pass or separately rendered sample range).
    pub fn merge(&mut self, other: &Coverage) {
        self.none = self.none.saturating_add(other.none);
        self.dropped = self.dropped.saturating_add(other.dropped);
        // Union of both id lists, equal ids summed, then the CAP best-ranked are kept.
        let mut union = [(0u32, 0u64); 2 * CAP];
        let mut n = 0;
        for (id, w) in self.entries().chain(other.entries()) {
            match union[..n].iter_mut().find(|e| e.0 == id) {
                Some(e) => e.1 = e.1.saturating_add(w),
                None => (union[n], n) = ((id, w), n + 1),
            }
        }
        if n > CAP {
            union[..n].sort_unstable_by(rank_order);
            for e in &union[CAP..n] {
                self.dropped = self.dropped.saturating_add(e.1);
            }
            n = CAP;
        }
        union[..n].sort_unstable_by_key(|e| e.0);
        (self.ids, self.weights, self.len) = ([0; CAP], [0; CAP], n as u8);
        for (k, e) in union[..n].iter().enumerate() {
            (self.ids[k], self.weights[k]) = *e;
        }
    }

    /// The kept (id, fixed-point weight) entries in ascending id order.
    fn entries(&self) -> impl Iterator<Item = (u32, u64)> + '_ {
        self.ids.iter().copied().zip(self.weights.iter().copied()).take(self.len())
    }

    /// The pixel's total weight in units of 2⁻³² (exact; [`Coverage::total_weight`]).
    pub fn total_units(&self) -> u128 {
        let kept: u128 = self.entries().map(|e| u128::from(e.1)).sum();
        kept + u128::from(self.none) + u128::from(self.dropped)
    }

    /// The pixel's total weight (ids, no-hit samples and dropped ids), in the caller's units.
    pub fn total_weight(&self) -> f64 {
        self.total_units() as f64 / 4_294_967_296.0
    }

    /// Weight of ids that did not fit in [`CAP`] (counted in the total, absent from the ranks).
    pub fn dropped_weight(&self) -> f64 {
        self.dropped as f64 / 4_294_967_296.0
    }

    /// Fills `out` with ranks 0, 1, …: `(id as float, weight / total weight)`, highest coverage
    /// first, ties by id bits ascending, padded with `(0.0, 0.0)`. No-hit weight is not ranked
    /// (Psyop's Arnold filter ranks it as id 0.0; decoders treat id 0.0 as background either way).
    pub fn write_ranks(&self, out: &mut [(f32, f32)]) {
        out.fill((0.0, 0.0));
        let total = self.total_units() as f64;
        let mut sorted = [(0u32, 0u64); CAP];
        let n = self.len();
        sorted.iter_mut().zip(self.entries()).for_each(|(s, e)| *s = e);
        sorted[..n].sort_unstable_by(rank_order);
        for (slot, e) in out.iter_mut().zip(&sorted[..n]) {
            *slot = (f32::from_bits(e.0), (e.1 as f64 / total) as f32);
        }
    }

    /// The first `n` ranks as [`write_ranks`](Self::write_ranks) gives them (allocates).
    pub fn ranks(&self, n: usize) -> Vec<(f32, f32)> {
        let mut out = vec![(0.0, 0.0); n];
        self.write_ranks(&mut out);
        out
    }

    /// Fills one RGBA pixel per rank layer: layer `i` = `[id 2i, cov 2i, id 2i+1, cov 2i+1]`.
    pub fn write_layers(&self, out: &mut [[f32; 4]]) {
        let mut ranks = [(0.0f32, 0.0f32); CAP];
        self.write_ranks(&mut ranks);
        for (i, px) in out.iter_mut().enumerate() {
            let a = ranks.get(2 * i).copied().unwrap_or_default();
            let b = ranks.get(2 * i + 1).copied().unwrap_or_default();
            *px = [a.0, a.1, b.0, b.1];
        }
    }

    /// Appends the compact encoding: a flags byte (bits 0-4 entry count, bit 5 no-hit weight
    /// follows, bit 6 dropped weight follows), those u64 weights, then (u32 id, u64 weight) per
    /// entry in ascending id order; all little-endian. An empty pixel is one byte.
    pub fn to_bytes(&self, out: &mut Vec<u8>) {
        out.push(self.len | u8::from(self.none != 0) << 5 | u8::from(self.dropped != 0) << 6);
        for extra in [self.none, self.dropped] {
            if extra != 0 {
                out.extend_from_slice(&extra.to_le_bytes());
            }
        }
        for (id, w) in self.entries() {
            out.extend_from_slice(&id.to_le_bytes());
            out.extend_from_slice(&w.to_le_bytes());
        }
    }

    /// Decodes one pixel from the start of `bytes`, returning it and the bytes consumed.
    ///
    /// Only the canonical encoding is accepted: more than [`CAP`] entries, a reserved bit, a
    /// flagged zero weight, zero or non-canonical ids (bits that would be NaN, infinite, zero or
    /// denormal floats), ids not strictly ascending, zero entry weights and truncation are
    /// errors. Weights are unsigned integers, so negative or non-finite ones cannot be encoded.
    pub fn from_bytes(bytes: &[u8]) -> Result<(Coverage, usize), String> {
        let mut pos = 0usize;
        let mut take = |n: usize| -> Result<&[u8], String> {
            let end = pos.checked_add(n).filter(|&e| e <= bytes.len());
            let end = end.ok_or_else(|| format!("truncated at byte {pos}"))?;
            let s = &bytes[pos..end];
            pos = end;
            Ok(s)
        };
        let le = |s: &[u8]| s.iter().rev().fold(0u64, |v, &b| v << 8 | u64::from(b));
        let flags = take(1)?[0];
        if flags & 0x80 != 0 {
            return Err("reserved flag bit set".into());
        }
        let len = usize::from(flags & 0x1f);
        if len > CAP {
            return Err(format!("{len} entries exceed the capacity {CAP}"));
        }
        let mut c = Coverage::new();
        for (bit, slot) in [(0x20u8, &mut c.none), (0x40, &mut c.dropped)] {
            if flags & bit != 0 {
                *slot = le(take(8)?);
                if *slot == 0 {
                    return Err("flagged weight is zero".into());
                }
            }
        }
        for k in 0..len {
            let e = take(12)?;
            let (id, w) = (le(&e[..4]) as u32, le(&e[4..]));
            if id == 0 || hash_to_float(id).to_bits() != id {
                return Err(format!("entry {k}: {id:08x} is not a valid id"));
            }
            if k > 0 && id <= c.ids[k - 1] {
                return Err(format!("entry {k}: ids not strictly ascending"));
            }
            if w == 0 {
                return Err(format!("entry {k}: zero weight"));
            }
            c.ids[k] = id;
            c.weights[k] = w;
        }
        c.len = len as u8;
        Ok((c, pos))
    }
}

/// The type of the object mattes: each shape's object name ([`crate::scene::Scene::objects`]).
pub const OBJECT: &str = "CryptoObject";
/// The type of the material mattes: each shape's material name
/// ([`crate::scene::Scene::material_name`]).
pub const MATERIAL: &str = "CryptoMaterial";

/// One Cryptomatte type of a film: its name, the manifest of the names its ids hash, and its
/// pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct Matte {
    /// The type's name (`CryptoObject`, `CryptoMaterial`): its layers' prefix.
    pub kind: String,
    /// The manifest JSON ([`manifest`]).
    pub manifest: String,
    pub pixels: MattePixels,
}

/// A matte's pixels: what a render accumulates, or what an image holds.
#[derive(Clone, Debug, PartialEq)]
pub enum MattePixels {
    /// Each pixel's coverage by id, exact ([`Coverage`]): a render's, a part file's.
    Coverage(Vec<Coverage>),
    /// The rank layers' channels (`<kind>00.R`, `<kind>00.G`, …), as an image read back has
    /// them: written again unchanged.
    Ranks(crate::film::Channels),
}

impl Matte {
    /// A matte of type `kind` over the ids of `names`, for `pixels` pixels not yet sampled.
    pub fn new(kind: &str, names: &[&str], pixels: usize) -> Matte {
        Matte {
            kind: kind.to_string(),
            manifest: manifest(names),
            pixels: MattePixels::Coverage(vec![Coverage::new(); pixels]),
        }
    }

    /// The four header attributes of the type ([`header`]).
    pub fn attributes(&self) -> Vec<(String, String)> {
        attributes(&self.kind, ("manifest", self.manifest.clone()))
    }

    /// Each pixel's coverage, when the matte has them (not read from an image).
    pub fn coverage(&self) -> Option<&[Coverage]> {
        match &self.pixels {
            MattePixels::Coverage(c) => Some(c),
            MattePixels::Ranks(_) => None,
        }
    }

    pub fn coverage_mut(&mut self) -> Option<&mut [Coverage]> {
        match &mut self.pixels {
            MattePixels::Coverage(c) => Some(c),
            MattePixels::Ranks(_) => None,
        }
    }

    /// Bytes of its pixels.
    pub fn bytes(&self) -> u64 {
        match &self.pixels {
            MattePixels::Coverage(c) => (c.capacity() * size_of::<Coverage>()) as u64,
            MattePixels::Ranks(r) => r.iter().map(|(_, v)| (v.capacity() * size_of::<f32>()) as u64).sum(),
        }
    }

    /// The rank layers' channels, [`DEFAULT_RANKS`] ranks of the coverage (or those read).
    pub fn rank_channels(&self) -> crate::film::Channels {
        let coverage = match &self.pixels {
            MattePixels::Ranks(r) => return r.clone(),
            MattePixels::Coverage(c) => c,
        };
        let layers = DEFAULT_RANKS.div_ceil(2);
        let mut px = vec![[0.0f32; 4]; layers];
        let mut out: Vec<(String, Vec<f32>)> = channel_names(&self.kind, DEFAULT_RANKS)
            .into_iter()
            .map(|name| (name, Vec::with_capacity(coverage.len())))
            .collect();
        for c in coverage {
            c.write_layers(&mut px);
            for (k, (_, values)) in out.iter_mut().enumerate() {
                values.push(px[k / 4][k % 4]);
            }
        }
        out
    }

    /// The matte of the ids `ids` ([`name_id`]): each pixel's summed coverage of them, as a
    /// compositor reads it from the rank layers.
    pub fn matte(&self, ids: &[u32]) -> Vec<f32> {
        let ranks = self.rank_channels();
        let n = ranks.first().map_or(0, |(_, v)| v.len());
        let mut out = vec![0.0f32; n];
        for pair in ranks.chunks_exact(2) {
            let (id, cov) = (&pair[0].1, &pair[1].1);
            for ((o, i), c) in out.iter_mut().zip(id).zip(cov) {
                if ids.contains(&i.to_bits()) && i.to_bits() != 0 {
                    *o += c;
                }
            }
        }
        out
    }

    /// The mattes an image holds: one per `cryptomatte/<key>/name` attribute of `attributes`,
    /// with its manifest (`{}` when the file has none or keeps it in a sidecar) and its rank
    /// layers `<name>00`, `<name>01`, … from `channels` (at least one, each with R, G, B, A).
    pub fn read_all(
        attributes: &[(String, String)],
        channels: &crate::film::Channels,
        pixels: usize,
    ) -> Result<Vec<Matte>, String> {
        let find = |name: &str| channels.iter().find(|(c, _)| c == name);
        let mut out = Vec::new();
        for (kind, manifest) in Matte::types(attributes)? {
            let mut ranks = Vec::new();
            for layer in (0..100).map(|i| format!("{kind}{i:02}")) {
                // Some writers name the channels `r g b a`.
                let find_either = |c: &str| {
                    find(&format!("{layer}.{c}")).or_else(|| find(&format!("{layer}.{}", c.to_lowercase())))
                };
                let found: Vec<_> = CHANNELS.iter().map(|c| find_either(c)).collect();
                if found.iter().all(Option::is_none) {
                    break;
                }
                for (c, f) in CHANNELS.iter().zip(found) {
                    let (name, values) = f.ok_or_else(|| format!("no `{layer}.{c}` channel"))?;
                    if values.len() != pixels {
                        return Err("channel sizes do not match the image".into());
                    }
                    ranks.push((name.clone(), values.clone()));
                }
            }
            if ranks.is_empty() {
                return Err(format!("Cryptomatte `{kind}` has no `{kind}00` layer"));
            }
            out.push(Matte { kind, manifest, pixels: MattePixels::Ranks(ranks) });
        }
        Ok(out)
    }

    /// The types header attributes name (`cryptomatte/<key>/name`), each with its manifest
    /// (`{}` when there is none or it is in a sidecar file), sorted by name.
    pub fn types(attributes: &[(String, String)]) -> Result<Vec<(String, String)>, String> {
        let mut out = Vec::new();
        for (attr, kind) in attributes {
            let Some(key) = attr.strip_prefix("cryptomatte/").and_then(|k| k.strip_suffix("/name")) else {
                continue;
            };
            // Read more widely than written: Blender names its types `ViewLayer.CryptoObject`.
            if kind.is_empty() || kind.chars().any(char::is_control) {
                return Err(format!("Cryptomatte `{attr}` names `{kind}`, which cannot name layers"));
            }
            let manifest = attributes
                .iter()
                .find(|(a, _)| *a == format!("cryptomatte/{key}/manifest"))
                .map_or_else(|| "{}".to_string(), |(_, m)| m.clone());
            out.push((kind.clone(), manifest));
        }
        out.sort();
        Ok(out)
    }

    /// The coverage as whole-number channels for a part file, exact: `<prefix>.none` and
    /// `.dropped` (each a `.hi` and `.lo` word), then for each slot `k` below the most ids a
    /// pixel has, `<prefix>.id<k>` and `<prefix>.w<k>` (`.hi`, `.lo`); a pixel's ids in ascending
    /// order, its unused slots 0. Nothing for a matte read from an image.
    pub fn words(&self, prefix: &str) -> crate::film::Words {
        let Some(coverage) = self.coverage() else { return Vec::new() };
        let slots = coverage.iter().map(Coverage::len).max().unwrap_or(0);
        let mut out = Vec::new();
        let mut wide = |name: String, of: &dyn Fn(&Coverage) -> u64| {
            out.push((format!("{name}.hi"), coverage.iter().map(|c| (of(c) >> 32) as u32).collect()));
            out.push((format!("{name}.lo"), coverage.iter().map(|c| of(c) as u32).collect()));
        };
        wide(format!("{prefix}.none"), &|c| c.none);
        wide(format!("{prefix}.dropped"), &|c| c.dropped);
        for k in 0..slots {
            wide(format!("{prefix}.w{k}"), &|c| c.weights[k]);
        }
        for k in 0..slots {
            out.push((format!("{prefix}.id{k}"), coverage.iter().map(|c| c.ids[k]).collect()));
        }
        out
    }

    /// A matte of type `kind` with `manifest` from the part file channels [`Matte::words`]
    /// wrote, checked as [`Coverage::from_bytes`] checks its encoding.
    pub fn from_words(
        kind: &str,
        manifest: String,
        prefix: &str,
        words: &crate::film::Words,
        pixels: usize,
    ) -> Result<Matte, String> {
        let find = |name: &str| -> Option<&Vec<u32>> {
            words.iter().find(|(w, _)| w == name).map(|(_, d)| d).filter(|d| d.len() == pixels)
        };
        let need =
            |name: String| find(&name).ok_or_else(|| format!("no `{name}` channel of the image's size"));
        let wide = |name: String| -> Result<Vec<u64>, String> {
            let (hi, lo) = (need(format!("{name}.hi"))?, need(format!("{name}.lo"))?);
            Ok(hi.iter().zip(lo).map(|(&h, &l)| u64::from(h) << 32 | u64::from(l)).collect())
        };
        let (none, dropped) = (wide(format!("{prefix}.none"))?, wide(format!("{prefix}.dropped"))?);
        let mut slots = Vec::new();
        while find(&format!("{prefix}.id{}", slots.len())).is_some() {
            let k = slots.len();
            if k == CAP {
                return Err(format!("`{prefix}` has more than {CAP} ids a pixel"));
            }
            slots.push((need(format!("{prefix}.id{k}"))?, wide(format!("{prefix}.w{k}"))?));
        }
        let mut bytes = Vec::with_capacity(MAX_ENCODED_LEN);
        let mut coverage = Vec::with_capacity(pixels);
        for i in 0..pixels {
            // The pixel's entries: its slots up to the first unused one, which all after must be.
            let used = slots.iter().take_while(|(id, _)| id[i] != 0).count();
            if slots[used..].iter().any(|(id, w)| id[i] != 0 || w[i] != 0) {
                return Err(format!("`{prefix}`: pixel {i} has an unused slot before a used one"));
            }
            bytes.clear();
            bytes.push(used as u8 | u8::from(none[i] != 0) << 5 | u8::from(dropped[i] != 0) << 6);
            for extra in [none[i], dropped[i]] {
                if extra != 0 {
                    bytes.extend_from_slice(&extra.to_le_bytes());
                }
            }
            for (id, w) in &slots[..used] {
                bytes.extend_from_slice(&id[i].to_le_bytes());
                bytes.extend_from_slice(&w[i].to_le_bytes());
            }
            let (c, _) = Coverage::from_bytes(&bytes).map_err(|e| format!("`{prefix}`: pixel {i}: {e}"))?;
            coverage.push(c);
        }
        Ok(Matte { kind: kind.to_string(), manifest, pixels: MattePixels::Coverage(coverage) })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// xorshift64*: a small deterministic generator for randomised tests.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
        }
        fn below(&mut self, n: usize) -> usize {
            (self.next() % n as u64) as usize
        }
        /// A weight between 2^-20 and 2^10 with a random mantissa.
        fn weight(&mut self) -> f32 {
            f32::from_bits((self.below(30) as u32 + 107) << 23 | self.next() as u32 >> 9)
        }
    }

    fn id(n: u32) -> u32 {
        name_id(&format!("object_{n}"))
    }

    /// Accumulates (id, weight) samples; id 0 is a sample that hit nothing.
    fn acc(samples: &[(u32, f32)]) -> Coverage {
        let mut c = Coverage::new();
        samples.iter().for_each(|&(id, w)| c.add(id, w));
        c
    }

    fn rank_bits(c: &Coverage) -> Vec<(u32, u32)> {
        let r = c.ranks(CAP);
        r.iter().map(|p| (p.0.to_bits(), p.1.to_bits())).collect()
    }

    #[test]
    fn murmur3_reference_vectors() {
        // SMHasher self-test: aappleby/smhasher src/main.cpp lists verification value 0xB0F57EE3
        // for MurmurHash3_x86_32 ("Murmur3A"); the procedure is VerificationTest in KeysetTest.cpp.
        let (mut key, mut hashes) = ([0u8; 256], Vec::new());
        for i in 0..256 {
            key[i] = i as u8;
            hashes.extend(murmur3_32(&key[..i], 256 - i as u32).to_le_bytes());
        }
        assert_eq!(murmur3_32(&hashes, 0), 0xB0F5_7EE3);
        // Widely quoted vectors, cross-checked with Psyop/Cryptomatte nuke/pymmh3.py.
        let cases: [(&[u8], u32, u32); 10] = [
            (b"", 0, 0),
            (b"", 1, 0x514E_28B7),
            (b"", 0xffff_ffff, 0x81F1_6F39),
            (b"\0\0\0\0", 0, 0x2362_F9DE),
            (b"\xff\xff\xff\xff", 0, 0x7629_3B50),
            (b"!Ce\x87", 0, 0xF55B_516B),
            (b"!Ce", 0, 0x7E4A_8634),
            (b"!C", 0, 0xA0F7_B07A),
            (b"!", 0, 0x7266_1CF4),
            (b"Hello, world!", 0x9747_b28c, 0x2488_4CBA),
        ];
        for (data, seed, want) in cases {
            assert_eq!(murmur3_32(data, seed), want, "{data:?} seed {seed:#x}");
        }
    }

    #[test]
    #[allow(clippy::excessive_precision)] // literals quoted verbatim from their sources
    fn published_name_ids() {
        // Psyop/Cryptomatte specification/cryptomatte_specification.pdf, "Example code and conversions".
        assert_eq!(name_hash("torus"), 4053562365);
        assert_eq!(name_hash("torus") as i32, -241404931);
        assert_eq!(hash_to_float(name_hash("torus")), -1.54943624832e+30);
        assert_eq!(name_hash("равнина"), 2518896926);
        assert_eq!(hash_to_float(name_hash("равнина")), -1.31926312124e-25);
        // Psyop/Cryptomatte nuke/cryptomatte_utilities_tests.py, CryptoHashing.mm3hash_float_values.
        let floats: [(&str, f32); 5] = [
            ("hello", 6.0705627102400005616e-17),
            ("cube", -4.08461912519e+15),
            ("sphere", 2.79018604383e+15),
            ("plane", 3.66557617593e-11),
            ("mädchen", 6.2361298211599995797e+25),
        ];
        for (name, want) in floats {
            assert_eq!(hash_to_float(name_hash(name)), want, "{name}");
        }
        // The specification PDF's manifest example, then names from Psyop/Cryptomatte
        // sample_images/sidecar_manifest/bunny_CryptoObject_manifest.json whose raw hash has
        // exponent 255 or 0 (both signs), so the exponent toggle applies.
        for (name, raw, hex) in [
            ("bunny", 0x13851a76, "13851a76"),
            ("default", 0x42c9679f, "42c9679f"),
            ("bunny_porcelain_mat", 0xb24b26d4, "b24b26d4"),
            ("flowerA.flowerA_petal1.:1065", 0x7f8e5296, "7f0e5296"),
            ("flowerA.flowerA_petal13.:1823", 0xffd75310, "ff575310"),
            ("flowerA.flowerA_petal11.:778", 0x000586a5, "008586a5"),
            ("flowerA.flowerA_petal15.:2777", 0x800d002e, "808d002e"),
        ] {
            assert_eq!((name_hash(name), id_hex(name_id(name))), (raw, hex.into()));
        }
    }

    #[test]
    fn keys_and_headers_match_published_files() {
        // Header keys of Psyop/Cryptomatte sample_images/debug_images/multichannel.exr,
        // special_chars.exr and sample_images/cornellBox_CryptoWildcard.0001.exr, then the two
        // keys quoted in the specification PDF (its type labels there are only illustrative).
        let keys = "crypto_asset=28322e9 crypto_material=bda530a crypto_object=f834d0a \
            special_chars=fbb35e3 uCryptoWildcard=2ae4678 uCryptoAsset=d593dd7 uCryptoObject=ae93ba3";
        for (name, key) in keys.split(' ').filter_map(|p| p.split_once('=')) {
            assert_eq!(layer_key(name), key, "{name}");
        }
        // multichannel.exr's crypto_material attributes (written by Arnold), byte for byte.
        let names = [
            "/shop/mat3/standard_surface1_3",
            "/shop/mat1/standard_surface1",
            "/shop/mat2/standard_surface1",
            "/shop/mat3/standard_surface1",
        ];
        let want = [
            ("name", "crypto_material"),
            ("hash", "MurmurHash3_32"),
            ("conversion", "uint32_to_float32"),
            (
                "manifest",
                r#"{"\/shop\/mat1\/standard_surface1":"ff43f211","\/shop\/mat2\/standard_surface1":"33fa0e82","\/shop\/mat3\/standard_surface1":"0247c000","\/shop\/mat3\/standard_surface1_3":"f5809b3a"}"#,
            ),
        ];
        let want: Vec<_> =
            want.iter().map(|(k, v)| (format!("cryptomatte/bda530a/{k}"), v.to_string())).collect();
        assert_eq!(header("crypto_material", &names), want);
        let assets = manifest(&["toroidal_asset", "ball_asset", "ball_asset"]);
        assert_eq!(assets, r#"{"ball_asset":"79b62f5e","toroidal_asset":"1539c043"}"#);
        // Psyop/CryptomatteArnold tests/cryptomatte/001_correct/special_chars.special_chars.json
        let special = manifest(&["равнина", "name_containing/slash", "name containing a \"quote\"  "]);
        let want = r#"{"name containing a \"quote\"  ":"af8bfa09","name_containing\/slash":"b0a04231","равнина":"9623511e"}"#;
        assert_eq!(special, want);
        // sample_images/debug_images/sidecar_manifest.exr
        let side = sidecar_header("crypto_asset", "sidecar_manifest.crypto_asset.json");
        assert_eq!(side[3].0, "cryptomatte/28322e9/manif_file");
        assert_eq!(manifest(&[]), "{}");
    }

    #[test]
    fn manifest_escapes_control_characters() {
        let name = "\u{0}\u{1f}\n\t\r\u{8}\u{c}\"\\/\u{7f}ü😀";
        let m = manifest(&[name, "b", "", "b"]);
        let esc = r#""\u0000\u001f\n\t\r\b\f\"\\\/"#;
        let want = format!(
            "{{\"\":\"{}\",{esc}\u{7f}ü😀\":\"{}\",\"b\":\"{}\"}}",
            id_hex(name_id("")),
            id_hex(name_id(name)),
            id_hex(name_id("b"))
        );
        assert_eq!(m, want);
        assert!(!m.chars().any(|c| u32::from(c) < 0x20));
    }

    #[test]
    fn conversion_is_always_normal_and_idempotent() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let check = |h: u32| {
            let f = hash_to_float(h);
            assert!(f.is_normal(), "{h:08x} -> {f:e}");
            assert_eq!(hash_to_float(f.to_bits()).to_bits(), f.to_bits());
            let exp = (h >> 23) & 0xff;
            let toggled = if exp == 0 || exp == 255 { 1 << 23 } else { 0 };
            assert_eq!(f.to_bits(), h ^ toggled);
        };
        for sign in [0, 1u32 << 31] {
            for exp in [0u32, 1, 2, 127, 253, 254, 255] {
                for mantissa in [0, 1, 0x40_0000, 0x7f_ffff, 0x12_3456] {
                    check(sign | exp << 23 | mantissa);
                }
            }
        }
        (0..1_000_000).for_each(|_| check(rng.next() as u32));
    }

    #[test]
    fn ranks_order_padding_and_covered_fraction() {
        let c = acc(&[(id(1), 1.0), (id(2), 3.0), (id(1), 1.0), (id(3), 2.0), (0, 1.0)]);
        let f = f32::from_bits;
        let (lo, hi) = (f(id(1).min(id(3))), f(id(1).max(id(3))));
        let want = [(f(id(2)), 0.375), (lo, 0.25), (hi, 0.25), (0.0, 0.0), (0.0, 0.0)];
        assert_eq!(c.ranks(5), want);
        assert_eq!(c.ranks(1), want[..1]);
        let mut layers = [[1.0f32; 4]; 3];
        c.write_layers(&mut layers);
        let l0 = [f(id(2)), 0.375, lo, 0.25];
        assert_eq!(layers, [l0, [hi, 0.25, 0.0, 0.0], [0.0; 4]]);
        assert_eq!(Coverage::new().ranks(2), [(0.0, 0.0); 2]);
        // A raw hash and its id are one entry; NaN, infinite, negative, zero weights are ignored.
        let name = "flowerA.flowerA_petal1.:1065";
        let mut d = acc(&[(0, 1.0), (name_hash(name), 1.0), (name_id(name), 1.0)]);
        for w in [f32::NAN, -1.0, f32::INFINITY, f32::NEG_INFINITY, 0.0] {
            d.add(id(9), w);
            d.add_none(w);
        }
        assert_eq!((d.len(), d.total_weight()), (1, 3.0));
        let third = (2.0f64 / 3.0) as f32;
        assert_eq!(d.ranks(2), [(f(name_id(name)), third), (0.0, 0.0)]);
        // Random pixels: the ranks sum to the covered fraction.
        let mut rng = Rng(5);
        for _ in 0..200 {
            let s: Vec<(u32, f32)> = (0..rng.below(40))
                .map(|_| (rng.below(CAP + 4) as u32, rng.weight()))
                .map(|(n, w)| (if n < 4 { 0 } else { id(n) }, w))
                .collect();
            let total: f64 = s.iter().map(|p| f64::from(p.1)).sum();
            let hit: f64 = s.iter().filter(|p| p.0 != 0).map(|p| f64::from(p.1)).sum();
            let sum: f64 = acc(&s).ranks(CAP).iter().map(|p| f64::from(p.1)).sum();
            let want = if hit > 0.0 { hit / total } else { 0.0 };
            assert!((sum - want).abs() < 1e-5, "{sum} vs {want}");
        }
    }

    #[test]
    fn overflow_keeps_heaviest_and_true_total() {
        let up: Vec<(u32, f32)> = (0..20u32).map(|n| (id(n), n as f32 + 1.0)).collect();
        let down: Vec<(u32, f32)> = up.iter().rev().copied().collect();
        let mut c = acc(&up);
        assert_eq!(c, acc(&down));
        assert_eq!((c.len(), c.dropped_weight(), c.total_weight()), (CAP, 10.0, 210.0));
        let r = c.ranks(CAP + 2);
        assert_eq!(r[0], (f32::from_bits(id(19)), (20.0f64 / 210.0) as f32));
        let mut kept: Vec<u32> = r[..CAP].iter().map(|p| p.0.to_bits()).collect();
        let mut want: Vec<u32> = (4..20).map(id).collect();
        kept.sort_unstable();
        want.sort_unstable();
        assert_eq!((kept, &r[CAP..]), (want, &[(0.0, 0.0); 2][..]));
        // An id evicted at once and hit again later restarts from its later weight.
        c.add(id(100), 0.5);
        c.add(id(100), 100.0);
        assert_eq!((c.total_weight(), c.dropped_weight()), (310.5, 15.5));
        assert_eq!(c.ranks(1)[0].0.to_bits(), id(100));
        // Merging two overflowing parts is symmetric and keeps the exact total.
        let a = acc(&(0..14).map(|n| (id(n), n as f32 + 1.0)).collect::<Vec<_>>());
        let b = acc(&(7..21).map(|n| (id(n), 2.0 * n as f32)).collect::<Vec<_>>());
        let (mut ab, mut ba) = (a, b);
        ab.merge(&b);
        ba.merge(&a);
        assert_eq!(ab, ba);
        assert_eq!(ab.total_weight(), a.total_weight() + b.total_weight());
    }

    #[test]
    fn merging_parts_is_bit_identical_to_one_accumulator() {
        let mut rng = Rng(7);
        for _ in 0..300 {
            // At most CAP ids plus "nothing"; weights spanning 30 octaves stress rounding.
            let ids: Vec<u32> = (0..=rng.below(CAP)).map(|_| rng.next() as u32).collect();
            let mut s: Vec<(u32, f32)> = (0..rng.below(80))
                .map(|_| (ids.get(rng.below(ids.len() + 1)).map_or(0, |&i| i), rng.weight()))
                .collect();
            let whole = acc(&s);
            let mut cut = [rng.below(s.len() + 1), rng.below(s.len() + 1)];
            cut.sort_unstable();
            let p = [acc(&s[..cut[0]]), acc(&s[cut[0]..cut[1]]), acc(&s[cut[1]..])];
            let (mut left, mut tail, mut reversed) = (p[0], p[1], p[2]);
            left.merge(&p[1]);
            left.merge(&p[2]);
            tail.merge(&p[2]);
            let mut right = p[0];
            right.merge(&tail);
            reversed.merge(&p[1]);
            reversed.merge(&p[0]);
            for i in (1..s.len()).rev() {
                s.swap(i, rng.below(i + 1));
            }
            for c in [left, right, reversed, acc(&s)] {
                assert_eq!((c, rank_bits(&c)), (whole, rank_bits(&whole)));
            }
        }
    }

    #[test]
    fn serialisation_round_trips() {
        let mut rng = Rng(11);
        let (mut stream, mut all) = (Vec::new(), Vec::new());
        for _ in 0..200 {
            let n = rng.below(24);
            let c = acc(&(0..n).map(|_| (rng.next() as u32, rng.weight())).collect::<Vec<_>>());
            c.to_bytes(&mut stream);
            all.push(c);
        }
        assert!(all.iter().any(|c| c.dropped_weight() > 0.0));
        let mut pos = 0;
        for c in &all {
            let (d, used) = Coverage::from_bytes(&stream[pos..]).unwrap();
            assert_eq!((d, used <= MAX_ENCODED_LEN), (*c, true));
            pos += used;
        }
        assert_eq!(pos, stream.len());
        let mut empty = Vec::new();
        Coverage::new().to_bytes(&mut empty);
        assert_eq!(empty, [0]);
    }

    /// A part file's words give back every pixel exactly (none, dropped, up to [`CAP`] ids), and
    /// a pixel with a used slot after an unused one, or a channel missing, is refused.
    #[test]
    fn part_file_words_round_trip_and_gaps_are_refused() {
        let mut rng = Rng(5);
        let pixels: Vec<Coverage> = (0..300)
            .map(|_| {
                let n = rng.below(24);
                acc(&(0..n)
                    .map(|_| ((rng.next() as u32) * (rng.below(5) != 0) as u32, rng.weight()))
                    .collect::<Vec<_>>())
            })
            .collect();
        assert!(pixels.iter().any(|c| c.dropped_weight() > 0.0) && pixels.iter().any(Coverage::is_empty));
        let matte =
            Matte { kind: OBJECT.into(), manifest: "{}".into(), pixels: MattePixels::Coverage(pixels) };
        let words = matte.words("sums.CryptoObject");
        let back = Matte::from_words(OBJECT, "{}".into(), "sums.CryptoObject", &words, 300).expect("reads");
        assert_eq!(back, matte);
        // Pixel 0's first id moved past an unused slot.
        let mut gap = words.clone();
        let last = (0..CAP)
            .rev()
            .find(|k| gap.iter().any(|(n, _)| *n == format!("sums.CryptoObject.id{k}")))
            .unwrap();
        let i = (0..300).find(|&i| matte.coverage().unwrap()[i].len() == 1).expect("a pixel of one id");
        let slot = |k: usize| format!("sums.CryptoObject.id{k}");
        let moved = gap.iter().find(|(n, _)| *n == slot(0)).unwrap().1[i];
        gap.iter_mut().find(|(n, _)| *n == slot(0)).unwrap().1[i] = 0;
        gap.iter_mut().find(|(n, _)| *n == slot(last)).unwrap().1[i] = moved;
        let err = Matte::from_words(OBJECT, "{}".into(), "sums.CryptoObject", &gap, 300).unwrap_err();
        assert!(err.contains("unused slot"), "{err}");
        let missing: crate::film::Words =
            words.into_iter().filter(|(n, _)| !n.ends_with(".none.lo")).collect();
        assert!(Matte::from_words(OBJECT, "{}".into(), "sums.CryptoObject", &missing, 300).is_err());
    }

    /// The rank channels are [`DEFAULT_RANKS`] ranks in three RGBA layers, and a matte of ids
    /// sums the coverage of the ranks holding them.
    #[test]
    fn rank_channels_and_mattes() {
        let (a, b, c) = (id(1), id(2), id(3));
        let pixels = vec![acc(&[(a, 1.0), (a, 1.0), (b, 1.0), (0, 1.0)]), acc(&[(c, 2.0)]), Coverage::new()];
        let matte =
            Matte { kind: OBJECT.into(), manifest: "{}".into(), pixels: MattePixels::Coverage(pixels) };
        let ranks = matte.rank_channels();
        let names: Vec<&str> = ranks.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, channel_names(OBJECT, DEFAULT_RANKS));
        assert_eq!(ranks[0].1, [f32::from_bits(a), f32::from_bits(c), 0.0]);
        assert_eq!(ranks[1].1, [0.5, 1.0, 0.0]);
        assert_eq!(ranks[3].1, [0.25, 0.0, 0.0]);
        assert_eq!(matte.matte(&[a]), [0.5, 0.0, 0.0]);
        assert_eq!(matte.matte(&[a, b, c]), [0.75, 1.0, 0.0]);
        // Read back from an image, the same ranks and mattes.
        let attrs = matte.attributes();
        let read = Matte::read_all(&attrs, &ranks, 3).expect("reads");
        assert_eq!(read.len(), 1);
        assert_eq!((read[0].rank_channels(), read[0].matte(&[b])), (ranks.clone(), vec![0.25, 0.0, 0.0]));
        // Blender's naming: a view layer's prefix in the type, lower-case channels.
        let kind = "ViewLayer.CryptoObject";
        let attrs = attributes(kind, ("manifest", "{}".to_string()));
        let lower: crate::film::Channels = ranks
            .iter()
            .map(|(n, v)| {
                (
                    n.replacen(OBJECT, kind, 1).to_lowercase().replacen(&kind.to_lowercase(), kind, 1),
                    v.clone(),
                )
            })
            .collect();
        let read = Matte::read_all(&attrs, &lower, 3).expect("reads Blender's");
        assert_eq!(read[0].matte(&[a]), [0.5, 0.0, 0.0]);
    }

    #[test]
    fn hostile_bytes_are_rejected_without_panicking() {
        let mut ok = Vec::new();
        acc(&[(id(1), 1.0), (id(2), 2.0), (0, 0.5)]).to_bytes(&mut ok);
        for cut in 0..ok.len() {
            assert!(Coverage::from_bytes(&ok[..cut]).is_err(), "prefix {cut}");
        }
        let entry = |id: u32, w: u64| [&id.to_le_bytes()[..], &w.to_le_bytes()].concat();
        let one = |id, w| [vec![1u8], entry(id, w)].concat();
        let (lo, hi) = (id(1).min(id(2)), id(1).max(id(2)));
        let bad = [
            vec![17],                                           // more entries than CAP
            vec![0x1f],                                         // 31 entries
            vec![0x80],                                         // reserved bit
            [vec![0x20], 0u64.to_le_bytes().to_vec()].concat(), // flagged zero no-hit weight
            [vec![0x40], 0u64.to_le_bytes().to_vec()].concat(), // flagged zero dropped weight
            one(0, 1),
            one(0x7fc0_0000, 1), // NaN
            one(0x7f80_0000, 1), // +inf
            one(0xff80_0000, 1), // -inf
            one(0x0000_0001, 1), // denormal
            one(0x8000_0000, 1), // -0.0
            one(id(1), 0),
            [vec![2u8], entry(lo, 1), entry(lo, 1)].concat(),
            [vec![2u8], entry(hi, 1), entry(lo, 1)].concat(),
        ];
        for b in &bad {
            assert!(Coverage::from_bytes(b).is_err(), "{b:?}");
        }
        // Random bytes never panic, and whatever decodes is the canonical encoding.
        let mut rng = Rng(3);
        for _ in 0..20_000 {
            let mut bytes: Vec<u8> = (0..rng.below(64)).map(|_| rng.next() as u8).collect();
            if let Some(first) = bytes.first_mut().filter(|_| rng.below(2) == 0) {
                *first = rng.below(4) as u8 | (rng.below(4) as u8) << 5;
            }
            if let Ok((c, used)) = Coverage::from_bytes(&bytes) {
                let mut again = Vec::new();
                c.to_bytes(&mut again);
                assert_eq!(again, bytes[..used]);
            }
        }
    }

    #[test]
    fn layer_and_channel_names() {
        let layers = layer_names("CryptoObject", DEFAULT_RANKS);
        assert_eq!(layers, ["CryptoObject00", "CryptoObject01", "CryptoObject02"]);
        assert_eq!((layer_names("C", 5).len(), layer_names("C", 0).len()), (3, 0));
        assert_eq!(channel_names("C", 2), ["C00.R", "C00.G", "C00.B", "C00.A"]);
        assert!(is_portable_type_name("crypto_asset") && is_portable_type_name("CryptoObject"));
        for bad in ["", "2d", "a.b", "a b", "ümlaut"] {
            assert!(!is_portable_type_name(bad), "{bad}");
        }
    }
}
