//! The tables of `[[texture]]`, `[[material]]`, `[[shape]]` and `[[light]]`: each is read after its
//! `type` key into the section's enum of types, whose variants are structs that deny unknown keys.
//! Serde rejects a key the type does not take; this module says where, and which types take it.

use std::fmt;
use std::ops::Range;

use serde::de::{self, DeserializeOwned, DeserializeSeed, IntoDeserializer, MapAccess, Visitor};
use serde::Deserialize;
use toml_edit::{Item, Key, Value};

use super::Ctx;
use crate::scene::SceneError;

/// A section whose tables are picked by `type`: the enum of its types, with one newtype variant
/// per type, named as the `type` key writes it and holding a `deny_unknown_fields` struct.
pub(super) trait Typed: DeserializeOwned {
    /// The keys every type of the section takes besides `type` (a shape's `material`, say).
    type Common: DeserializeOwned;
    /// The section's name, as in `[[shape]]`.
    const SECTION: &'static str;
    /// Said after the list of types when a `type` is unknown.
    const HINT: &'static str = "";

    /// The variant a table of type `kind` reads as, given which keys it has: its `type`, unless
    /// the keys choose among variants of one type (a sky with `zenith` is cloudy).
    fn variant<'a>(kind: &'a str, _has: &dyn Fn(&str) -> bool) -> &'a str {
        kind
    }

    /// The `type` a variant is written as: the inverse of [`Typed::variant`].
    fn type_of(variant: &'static str) -> &'static str {
        variant
    }

    /// The variant in messages: "a sphere shape".
    fn describe(variant: &str) -> String {
        format!("{} {variant} {}", article(variant), Self::SECTION)
    }
}

/// "a" or "an", as `word` is said.
fn article(word: &str) -> &'static str {
    if word.starts_with(['a', 'e', 'i', 'o', 'u']) {
        "an"
    } else {
        "a"
    }
}

/// `a`, `a or b`, `a, b or c`.
fn or_list<S: AsRef<str>>(items: &[S]) -> String {
    match items {
        [] => String::new(),
        [one] => one.as_ref().to_string(),
        [init @ .., last] => {
            let init: Vec<&str> = init.iter().map(AsRef::as_ref).collect();
            format!("{} or {}", init.join(", "), last.as_ref())
        }
    }
}

/// The keys every light takes besides `type`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LightCommon {
    /// Its light group.
    pub light_group: Option<String>,
}

/// One table of a typed section, read.
pub(super) struct Table<K: Typed> {
    /// The `type` as written.
    pub kind: String,
    /// The keys every type takes.
    pub common: K::Common,
    /// The type's own keys.
    pub of_type: K,
    /// Where the table is (from its header on), for the errors of the pass that resolves it.
    pub span: Range<usize>,
}

/// A key of a table, where it is written, and its value.
struct Entry {
    key: String,
    span: Option<Range<usize>>,
    value: Value,
}

impl Entry {
    /// The entry `name = value`, placed at its key (or its value, when the key has no span).
    fn new(key: Option<&Key>, name: &str, value: Value) -> Entry {
        Entry { key: name.to_string(), span: key.and_then(Key::span).or_else(|| value.span()), value }
    }
}

/// Reads every table of the section `K` in the document `root` (`[[shape]]` headers, or an array
/// of inline tables) as the section's types.
pub(super) fn tables<K: Typed>(ctx: &Ctx, root: &toml_edit::Table) -> Result<Vec<Table<K>>, SceneError> {
    let section = K::SECTION;
    let mut raw: Vec<(Option<Range<usize>>, Vec<Entry>)> = Vec::new();
    match root.get(section) {
        None => {}
        Some(Item::ArrayOfTables(array)) => {
            for table in array.iter() {
                let entries = table
                    .iter()
                    .filter_map(|(k, item)| {
                        Some(Entry::new(table.key(k), k, item.clone().into_value().ok()?))
                    })
                    .collect();
                raw.push((table.span(), entries));
            }
        }
        Some(Item::Value(Value::Array(array))) => {
            for value in array.iter() {
                let Value::InlineTable(table) = value else {
                    return Err(ctx.error(value.span(), format!("each `{section}` must be a table")));
                };
                let entries = table.iter().map(|(k, v)| Entry::new(table.key(k), k, v.clone())).collect();
                raw.push((table.span(), entries));
            }
        }
        Some(other) => {
            return Err(ctx.error(
                other.span(),
                format!("`{section}` must be an array of tables, written `[[{section}]]`"),
            ))
        }
    }
    raw.into_iter().map(|(span, entries)| read(ctx, span, entries)).collect()
}

/// Reads one table: its `type`, then the keys every type takes, then the type's own.
fn read<K: Typed>(
    ctx: &Ctx,
    span: Option<Range<usize>>,
    mut entries: Vec<Entry>,
) -> Result<Table<K>, SceneError> {
    let span = span.or_else(|| entries.first().and_then(|e| e.span.clone())).unwrap_or(0..0);
    let section = K::SECTION;
    let Some(at) = entries.iter().position(|e| e.key == "type") else {
        let message = format!("{} {section} needs a `type` ({})", article(section), or_list(&types::<K>()));
        return Err(ctx.error(Some(span), message));
    };
    let type_entry = entries.remove(at);
    let Some(kind) = type_entry.value.as_str().map(str::to_string) else {
        return Err(ctx.error(type_entry.span, "`type` must be a string"));
    };
    let chosen = K::variant(&kind, &|key| entries.iter().any(|e| e.key == key));
    let Some(&variant) = names::<K>(None).iter().find(|&&v| v == chosen && K::type_of(v) == kind) else {
        let message =
            format!("unknown {section} type `{kind}` (expected {}{})", or_list(&types::<K>()), K::HINT);
        return Err(ctx.error(type_entry.value.span(), message));
    };
    let common_keys = names::<K::Common>(None);
    let (common, own): (Vec<Entry>, Vec<Entry>) =
        entries.into_iter().partition(|e| common_keys.contains(&e.key.as_str()));
    let fail = |e| explain::<K>(ctx, e, variant, &span);
    let common = K::Common::deserialize(Keys { variant, entries: common }).map_err(fail)?;
    let of_type = K::deserialize(Keys { variant, entries: own }).map_err(fail)?;
    Ok(Table { kind, common, of_type, span })
}

/// The `type`s of a section, in the order of its enum.
fn types<K: Typed>() -> Vec<&'static str> {
    let mut types = Vec::new();
    for t in names::<K>(None).iter().map(|&v| K::type_of(v)) {
        if !types.contains(&t) {
            types.push(t);
        }
    }
    types
}

/// The error of a table of `variant` (whose header is at `span`) that serde did not read: a key
/// no type takes where it is written, with the keys the type takes; a key of other types, or a
/// missing one, at the table.
fn explain<K: Typed>(ctx: &Ctx, e: KeyError, variant: &str, span: &Range<usize>) -> SceneError {
    let what = K::describe(variant);
    match e {
        KeyError::Unknown { key, span: at } => {
            let others: Vec<&str> = names::<K>(None)
                .iter()
                .filter(|&&v| v != variant && names::<K>(Some(v)).contains(&key.as_str()))
                .copied()
                .collect();
            if others.is_empty() {
                let expected: Vec<String> = names::<K>(Some(variant))
                    .iter()
                    .chain(names::<K::Common>(None))
                    .map(|k| format!("`{k}`"))
                    .collect();
                ctx.error(at, format!("unknown key `{key}` in {what} (expected {})", or_list(&expected)))
            } else {
                let section = K::SECTION;
                let message =
                    format!("{what} does not take `{key}` (only {} {section}s do)", or_list(&others));
                ctx.error(Some(span.clone()), message)
            }
        }
        KeyError::Missing(key) => ctx.error(Some(span.clone()), format!("{what} needs `{key}`")),
        KeyError::Value { message, span: at } => ctx.error(at.or(Some(span.clone())), message),
    }
}

/// Why a table did not read as its type.
#[derive(Debug)]
enum KeyError {
    /// A key the type's struct does not have, and where it is written.
    Unknown { key: String, span: Option<Range<usize>> },
    /// A key the type needs and the table lacks.
    Missing(&'static str),
    /// A value that is not what its key wants (TOML's message), and where.
    Value { message: String, span: Option<Range<usize>> },
}

impl fmt::Display for KeyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            KeyError::Unknown { key, .. } => write!(f, "unknown key `{key}`"),
            KeyError::Missing(key) => write!(f, "missing key `{key}`"),
            KeyError::Value { message, .. } => f.write_str(message),
        }
    }
}

impl std::error::Error for KeyError {}

impl de::Error for KeyError {
    fn custom<T: fmt::Display>(message: T) -> Self {
        KeyError::Value { message: message.to_string(), span: None }
    }

    fn unknown_field(field: &str, _expected: &'static [&'static str]) -> Self {
        KeyError::Unknown { key: field.to_string(), span: None }
    }

    fn missing_field(field: &'static str) -> Self {
        KeyError::Missing(field)
    }
}

/// A table's keys (minus `type`) as serde reads them: a map for a struct, the enum variant
/// `variant` holding that map for the section's enum. Values go through `toml_edit`, so their
/// errors keep their spans.
struct Keys<'a> {
    variant: &'a str,
    entries: Vec<Entry>,
}

impl<'de> de::Deserializer<'de> for Keys<'_> {
    type Error = KeyError;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, KeyError> {
        visitor.visit_map(Entries { entries: self.entries.into_iter(), value: None })
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _name: &'static str,
        _variants: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, KeyError> {
        visitor.visit_enum(self)
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf option
        unit unit_struct newtype_struct seq tuple tuple_struct map struct identifier ignored_any
    }
}

impl<'de, 'a> de::EnumAccess<'de> for Keys<'a> {
    type Error = KeyError;
    type Variant = Keys<'a>;

    fn variant_seed<S: DeserializeSeed<'de>>(self, seed: S) -> Result<(S::Value, Keys<'a>), KeyError> {
        let variant = seed.deserialize(self.variant.into_deserializer())?;
        Ok((variant, self))
    }
}

impl<'de> de::VariantAccess<'de> for Keys<'_> {
    type Error = KeyError;

    fn unit_variant(self) -> Result<(), KeyError> {
        match self.entries.first() {
            Some(e) => Err(KeyError::Unknown { key: e.key.clone(), span: e.span.clone() }),
            None => Ok(()),
        }
    }

    fn newtype_variant_seed<S: DeserializeSeed<'de>>(self, seed: S) -> Result<S::Value, KeyError> {
        seed.deserialize(self)
    }

    fn tuple_variant<V: Visitor<'de>>(self, _len: usize, visitor: V) -> Result<V::Value, KeyError> {
        de::Deserializer::deserialize_any(self, visitor)
    }

    fn struct_variant<V: Visitor<'de>>(
        self,
        _fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, KeyError> {
        de::Deserializer::deserialize_any(self, visitor)
    }
}

/// The entries of a table, one key and value at a time.
struct Entries {
    entries: std::vec::IntoIter<Entry>,
    value: Option<(Value, Option<Range<usize>>)>,
}

impl<'de> MapAccess<'de> for Entries {
    type Error = KeyError;

    fn next_key_seed<S: DeserializeSeed<'de>>(&mut self, seed: S) -> Result<Option<S::Value>, KeyError> {
        let Some(entry) = self.entries.next() else { return Ok(None) };
        let at = entry.span.clone();
        self.value = Some((entry.value, entry.span));
        seed.deserialize(entry.key.into_deserializer()).map(Some).map_err(|e| match e {
            KeyError::Unknown { key, span: None } => KeyError::Unknown { key, span: at },
            e => e,
        })
    }

    fn next_value_seed<S: DeserializeSeed<'de>>(&mut self, seed: S) -> Result<S::Value, KeyError> {
        let (value, key_span) =
            self.value.take().ok_or_else(|| de::Error::custom("a value without a key"))?;
        let span = value.span().or(key_span);
        seed.deserialize(value.into_deserializer())
            .map_err(|e| KeyError::Value { message: e.message().to_string(), span: e.span().or(span) })
    }
}

/// The names serde knows for `T`: a struct's fields, an enum's variants, or (given `variant`) the
/// fields of that variant's struct. Asked of the types themselves, so no list of keys is kept
/// beside them.
fn names<T: DeserializeOwned>(variant: Option<&str>) -> &'static [&'static str] {
    match T::deserialize(Probe { variant }) {
        Err(Names(names)) => names,
        Ok(_) => &[],
    }
}

/// What a [`Probe`] found (an error, to stop serde as soon as it is known).
#[derive(Debug)]
struct Names(&'static [&'static str]);

impl fmt::Display for Names {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:?}", self.0)
    }
}

impl std::error::Error for Names {}

impl de::Error for Names {
    fn custom<T: fmt::Display>(_: T) -> Self {
        Names(&[])
    }
}

/// A deserializer that reads nothing and reports the names serde asks it for.
struct Probe<'a> {
    variant: Option<&'a str>,
}

impl<'de> de::Deserializer<'de> for Probe<'_> {
    type Error = Names;

    fn deserialize_any<V: Visitor<'de>>(self, _visitor: V) -> Result<V::Value, Names> {
        Err(Names(&[]))
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        fields: &'static [&'static str],
        _visitor: V,
    ) -> Result<V::Value, Names> {
        Err(Names(fields))
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _name: &'static str,
        variants: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Names> {
        match self.variant {
            None => Err(Names(variants)),
            Some(_) => visitor.visit_enum(self),
        }
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf option
        unit unit_struct newtype_struct seq tuple tuple_struct map identifier ignored_any
    }
}

impl<'de, 'a> de::EnumAccess<'de> for Probe<'a> {
    type Error = Names;
    type Variant = Probe<'a>;

    fn variant_seed<S: DeserializeSeed<'de>>(self, seed: S) -> Result<(S::Value, Probe<'a>), Names> {
        let variant = seed.deserialize(self.variant.unwrap_or_default().into_deserializer())?;
        Ok((variant, Probe { variant: None }))
    }
}

impl<'de> de::VariantAccess<'de> for Probe<'_> {
    type Error = Names;

    fn unit_variant(self) -> Result<(), Names> {
        Err(Names(&[]))
    }

    fn newtype_variant_seed<S: DeserializeSeed<'de>>(self, seed: S) -> Result<S::Value, Names> {
        seed.deserialize(self)
    }

    fn tuple_variant<V: Visitor<'de>>(self, _len: usize, _visitor: V) -> Result<V::Value, Names> {
        Err(Names(&[]))
    }

    fn struct_variant<V: Visitor<'de>>(
        self,
        fields: &'static [&'static str],
        _visitor: V,
    ) -> Result<V::Value, Names> {
        Err(Names(fields))
    }
}

#[cfg(test)]
mod tests {
    use super::super::light::LightKind;
    use super::super::shape::{ShapeCommon, ShapeKind};
    use super::*;
    use crate::scene::file::tests::{error_line, parse_str, MINIMAL};
    use crate::scene::Geometry;

    #[test]
    fn names_come_from_the_types() {
        assert_eq!(names::<ShapeKind>(None), ["sphere", "quad", "box", "mesh", "gltf", "terrain", "teapot"]);
        assert_eq!(names::<ShapeKind>(Some("sphere")), ["center", "radius"]);
        assert_eq!(
            names::<ShapeCommon>(None),
            ["name", "material", "object", "emission", "transform", "light_group"]
        );
        assert_eq!(names::<LightKind>(Some("cloudy sky"))[0], "zenith");
    }

    #[test]
    fn an_unknown_key_names_its_line_and_the_keys_of_the_type() {
        let (line, msg) =
            error_line(&format!("{MINIMAL}[[shape]]\ntype = \"sphere\"\nradius = 1\nradiuss = 2\n"));
        assert_eq!(line, Some(7), "{msg}");
        for needle in ["`radiuss`", "a sphere shape", "`center`", "`radius`", "`material`", "`transform`"] {
            assert!(msg.contains(needle), "{needle}: {msg}");
        }
        assert!(!msg.contains("vertices"), "{msg}");
    }

    #[test]
    fn a_key_of_other_types_names_them() {
        let (line, msg) =
            error_line(&format!("{MINIMAL}[[shape]]\ntype = \"sphere\"\nradius = 1\nresolution = 4\n"));
        assert_eq!(line, Some(4), "{msg}");
        assert!(msg.contains("a sphere shape does not take `resolution` (only terrain or teapot"), "{msg}");
    }

    #[test]
    fn a_missing_key_or_type_and_an_unknown_type() {
        let shape = format!("{MINIMAL}[[shape]]\n");
        for (extra, line, needle) in [
            ("type = \"sphere\"\n", 4, "a sphere shape needs `radius`"),
            ("radius = 1\n", 4, "a shape needs a `type` (sphere, quad, box, mesh, gltf, terrain or teapot)"),
            ("type = 3\n", 5, "`type` must be a string"),
            (
                "type = \"torus\"\n",
                5,
                "unknown shape type `torus` (expected sphere, quad, box, mesh, gltf, terrain",
            ),
        ] {
            let (l, msg) = error_line(&format!("{shape}{extra}"));
            assert_eq!(l, Some(line), "{msg}");
            assert!(msg.contains(needle), "{needle}: {msg}");
        }
    }

    #[test]
    fn errors_inside_a_value_keep_their_line() {
        let quad = "[[shape]]\ntype = \"quad\"\nvertices = [\n  [0, 0, 0],\n  [1, nan, 0],\n  [1, 1, 0],\n  [0, 1, 0],\n]\n";
        let (line, msg) = error_line(&format!("{MINIMAL}{quad}"));
        assert_eq!(line, Some(8), "{msg}");
        assert!(msg.contains("finite"), "{msg}");
        let sphere = "[[shape]]\ntype = \"sphere\"\nradius = 1\ntransform = { scael = 2 }\n";
        let (line, msg) = error_line(&format!("{MINIMAL}{sphere}"));
        assert_eq!(line, Some(7), "{msg}");
        assert!(msg.contains("scael"), "{msg}");
    }

    #[test]
    fn inline_tables_and_sub_tables_read_alike() {
        let radius = |text: &str| match parse_str(text).expect("parses").shapes[0].geometry {
            Geometry::Sphere { radius, .. } => radius,
            Geometry::Triangles(_) => f32::NAN,
        };
        let inline = "shape = [{ type = \"sphere\", radius = 1, transform = { scale = 2 } }]\n";
        assert_eq!(radius(&format!("{inline}{MINIMAL}")), 2.0);
        let sub = "[[shape]]\ntype = \"sphere\"\nradius = 1\n[shape.transform]\nscale = 2\n";
        assert_eq!(radius(&format!("{MINIMAL}{sub}")), 2.0);
        let (line, msg) = error_line(&format!("shape = 3\n{MINIMAL}"));
        assert_eq!(line, Some(1), "{msg}");
        assert!(msg.contains("[[shape]]"), "{msg}");
    }
}
