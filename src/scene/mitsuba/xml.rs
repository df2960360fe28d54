//! Mitsuba 3 scene XML read into a tree of objects, before any of it means a scene: `$name`
//! parameters (from `-D` overrides, then `<default>`s, which never replace a value already
//! given) substituted in every attribute, `<include>`s spliced in (a scene's children in place
//! of the include, another object as a child), typed properties parsed, and `<transform>`s
//! composed in f64. Files older than version 2.0.0 have their camelCase property names
//! upgraded to Mitsuba 3's snake_case. Every error names the file and line.
//!
//! Mitsuba's rules, as its parser (`src/core/parser.cpp`) applies them: a transform's
//! operations apply in document order (each left-multiplies the ones before), `matrix` is row
//! major, `lookat`'s frame has its x axis along `up x (target - origin)`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3};

/// How deep includes may nest (Mitsuba's own limit): deeper is a cycle, or as good as one.
const MAX_INCLUDE_DEPTH: usize = 15;

/// A property's value.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    Float(f64),
    Integer(i64),
    Boolean(bool),
    String(String),
    /// An `rgb`: one value is grey.
    Rgb(DVec3),
    /// A `spectrum` of one value (a constant); wavelength pairs are kept as pairs.
    Spectrum(Vec<(f64, f64)>),
    Point(DVec3),
    Vector(DVec3),
    Transform(DMat4),
}

/// A property, where it was written.
#[derive(Clone, Debug, PartialEq)]
pub struct Property {
    pub name: String,
    pub value: Value,
    pub at: Place,
}

/// A file and line.
#[derive(Clone, Debug, PartialEq)]
pub struct Place {
    pub file: PathBuf,
    pub line: u32,
}

impl std::fmt::Display for Place {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}", self.file.display(), self.line)
    }
}

/// An object of the scene: its tag (`shape`, `bsdf`, `emitter`, ...), its plugin `type`, its
/// `id` and `name` where given, its properties and the objects nested in it (or referred to by
/// `<ref>`, kept as references).
#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    pub tag: String,
    pub kind: String,
    pub id: Option<String>,
    pub name: Option<String>,
    pub properties: Vec<Property>,
    pub children: Vec<Child>,
    pub at: Place,
}

/// What an object holds besides its properties.
#[derive(Clone, Debug, PartialEq)]
pub enum Child {
    Object(Object),
    /// `<ref id="..." name="..."/>`: an object defined elsewhere, by its id.
    Ref {
        id: String,
        name: Option<String>,
        at: Place,
    },
}

impl Object {
    /// The property `name`, if given.
    pub fn get(&self, name: &str) -> Option<&Property> {
        self.properties.iter().find(|p| p.name == name)
    }
}

/// The tags of properties (the others are objects, or `transform`).
const PROPERTY_TAGS: &[&str] =
    &["float", "integer", "boolean", "string", "rgb", "spectrum", "point", "vector"];

/// Where a scene's relative file names are looked for, as Mitsuba's file resolver: the
/// directory of the scene file first (for the files its includes name too, wherever those
/// are), then each `<path value="..."/>` in the order given.
#[derive(Clone, Debug, PartialEq)]
pub struct Resolver {
    dirs: Vec<PathBuf>,
    /// The XML files read: the scene file and every file it includes.
    pub files: Vec<PathBuf>,
}

impl Resolver {
    /// The first directory holding `name`, else the scene's own (so that the error names it).
    pub fn resolve(&self, name: &str) -> PathBuf {
        let name = Path::new(name);
        if name.is_absolute() {
            return name.to_path_buf();
        }
        let found = self.dirs.iter().map(|d| d.join(name)).find(|p| p.exists());
        found.unwrap_or_else(|| self.dirs[0].join(name))
    }
}

/// Reads `path` as a scene: its root object (`<scene>`), with `overrides` (`-D name=value`)
/// taking precedence over its `<default>`s, and where its files are looked for.
pub fn read(path: &Path, overrides: &[(String, String)]) -> Result<(Object, Resolver), String> {
    let mut params: HashMap<String, String> = overrides.iter().cloned().collect();
    let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let mut reader =
        Reader { params: &mut params, depth: 0, resolver: Resolver { dirs: vec![dir], files: Vec::new() } };
    let root = reader.file(path)?;
    if root.tag != "scene" {
        return Err(format!("{}: the root element is <{}>, not <scene>", root.at, root.tag));
    }
    Ok((root, reader.resolver))
}

struct Reader<'a> {
    params: &'a mut HashMap<String, String>,
    depth: usize,
    resolver: Resolver,
}

impl Reader<'_> {
    fn file(&mut self, path: &Path) -> Result<Object, String> {
        if !self.resolver.files.iter().any(|f| f == path) {
            self.resolver.files.push(path.to_path_buf());
        }
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let doc = roxmltree::Document::parse(&text).map_err(|e| {
            let pos = e.pos();
            format!("{}:{}: not valid XML: {e}", path.display(), pos.row)
        })?;
        let root = doc.root_element();
        let version = root.attribute("version").unwrap_or("");
        let upgrade = version.split('.').next().and_then(|m| m.parse::<u32>().ok()).is_some_and(|m| m < 2);
        if root.tag_name().name() == "scene" && version.is_empty() {
            return Err(format!("{}:{}: <scene> has no `version`", path.display(), line(&doc, root)));
        }
        let file = File { path, doc: &doc, upgrade };
        self.object(&file, root)
    }

    /// The attribute `name` of `node`, its `$parameters` substituted (longest name first).
    fn attribute(&self, file: &File, node: roxmltree::Node, name: &str) -> Result<Option<String>, String> {
        let Some(raw) = node.attribute(name) else { return Ok(None) };
        substitute(raw, self.params).map(Some).map_err(|e| format!("{}: {e}", file.place(node)))
    }

    fn object(&mut self, file: &File, node: roxmltree::Node) -> Result<Object, String> {
        let tag = node.tag_name().name().to_string();
        let kind = self.attribute(file, node, "type")?.unwrap_or_default();
        if kind.is_empty() && tag != "scene" {
            return Err(format!("{}: <{tag}> has no `type`", file.place(node)));
        }
        let mut object = Object {
            tag,
            kind,
            id: self.attribute(file, node, "id")?,
            name: self.attribute(file, node, "name")?.map(|n| file.upgraded(n)),
            properties: Vec::new(),
            children: Vec::new(),
            at: file.place(node),
        };
        for child in node.children().filter(|n| n.is_element()) {
            let tag = child.tag_name().name();
            match tag {
                "default" => {
                    let name = self.required(file, child, "name")?;
                    let value = self.required(file, child, "value")?;
                    self.params.entry(name).or_insert(value);
                }
                "include" => {
                    if self.depth >= MAX_INCLUDE_DEPTH {
                        return Err(format!(
                            "{}: includes nest deeper than {MAX_INCLUDE_DEPTH} (a cycle?)",
                            file.place(child)
                        ));
                    }
                    let name = self.required(file, child, "filename")?;
                    let path = self.resolver.resolve(&name);
                    self.depth += 1;
                    let included =
                        self.file(&path).map_err(|e| format!("{}: include `{name}`: {e}", file.place(child)));
                    self.depth -= 1;
                    let included = included?;
                    if included.tag == "scene" {
                        object.properties.extend(included.properties);
                        object.children.extend(included.children);
                    } else {
                        object.children.push(Child::Object(included));
                    }
                }
                "path" => {
                    let dir = self.resolver.resolve(&self.required(file, child, "value")?);
                    self.resolver.dirs.push(dir);
                }
                "ref" => object.children.push(Child::Ref {
                    id: self.required(file, child, "id")?,
                    name: self.attribute(file, child, "name")?,
                    at: file.place(child),
                }),
                "transform" => {
                    let name = file.upgraded(self.required(file, child, "name")?);
                    let m = self.transform(file, child)?;
                    object.properties.push(Property {
                        name,
                        value: Value::Transform(m),
                        at: file.place(child),
                    });
                }
                t if PROPERTY_TAGS.contains(&t) => {
                    let name = file.upgraded(self.required(file, child, "name")?);
                    let value = self.property(file, child, t)?;
                    object.properties.push(Property { name, value, at: file.place(child) });
                }
                _ => object.children.push(Child::Object(self.object(file, child)?)),
            }
        }
        Ok(object)
    }

    fn required(&self, file: &File, node: roxmltree::Node, name: &str) -> Result<String, String> {
        self.attribute(file, node, name)?
            .ok_or_else(|| format!("{}: <{}> has no `{name}`", file.place(node), node.tag_name().name()))
    }

    fn property(&self, file: &File, node: roxmltree::Node, tag: &str) -> Result<Value, String> {
        let here = file.place(node);
        let value = || self.required(file, node, "value");
        let bad = |what: &str, v: &str| format!("{here}: <{tag}> `{v}` is not {what}");
        Ok(match tag {
            "float" => {
                let v = value()?;
                Value::Float(v.trim().parse().map_err(|_| bad("a number", &v))?)
            }
            "integer" => {
                let v = value()?;
                Value::Integer(v.trim().parse().map_err(|_| bad("an integer", &v))?)
            }
            "boolean" => {
                let v = value()?;
                Value::Boolean(match v.trim().to_ascii_lowercase().as_str() {
                    "true" => true,
                    "false" => false,
                    _ => return Err(bad("true or false", &v)),
                })
            }
            "string" => Value::String(value()?),
            "rgb" => {
                let v = value()?;
                match numbers(&v).as_deref() {
                    Some([g]) => Value::Rgb(DVec3::splat(*g)),
                    Some([r, g, b]) => Value::Rgb(DVec3::new(*r, *g, *b)),
                    _ => return Err(bad("one or three numbers", &v)),
                }
            }
            "spectrum" => {
                let v = value()?;
                if let Some([x]) = numbers(&v).as_deref() {
                    Value::Spectrum(vec![(0.0, *x)])
                } else {
                    let pairs: Option<Vec<(f64, f64)>> = v
                        .split(',')
                        .map(|p| {
                            let (l, x) = p.split_once(':')?;
                            Some((l.trim().parse().ok()?, x.trim().parse().ok()?))
                        })
                        .collect();
                    Value::Spectrum(pairs.ok_or_else(|| bad("a number or wavelength:value pairs", &v))?)
                }
            }
            _ => {
                let v = self.vector(file, node, 0.0)?;
                if tag == "point" {
                    Value::Point(v)
                } else {
                    Value::Vector(v)
                }
            }
        })
    }

    /// A vector from `x`, `y`, `z` (each `default` when missing) or `value` (one or three
    /// numbers).
    fn vector(&self, file: &File, node: roxmltree::Node, default: f64) -> Result<DVec3, String> {
        let here = file.place(node);
        if let Some(v) = self.attribute(file, node, "value")? {
            return match numbers(&v).as_deref() {
                Some([x]) => Ok(DVec3::splat(*x)),
                Some([x, y, z]) => Ok(DVec3::new(*x, *y, *z)),
                _ => Err(format!("{here}: `{v}` is not one or three numbers")),
            };
        }
        let mut out = DVec3::splat(default);
        for (k, axis) in ["x", "y", "z"].iter().enumerate() {
            if let Some(v) = self.attribute(file, node, axis)? {
                out[k] = v.trim().parse().map_err(|_| format!("{here}: `{axis}=\"{v}\"` is not a number"))?;
            }
        }
        Ok(out)
    }

    /// A `<transform>`'s operations, each left-multiplying the ones before.
    fn transform(&self, file: &File, node: roxmltree::Node) -> Result<DMat4, String> {
        let mut m = DMat4::IDENTITY;
        for op in node.children().filter(|n| n.is_element()) {
            let here = file.place(op);
            let step = match op.tag_name().name() {
                "translate" => DMat4::from_translation(self.vector(file, op, 0.0)?),
                "scale" => DMat4::from_scale(self.vector(file, op, 1.0)?),
                "rotate" => {
                    let axis = self.vector(file, op, 0.0)?;
                    let angle: f64 = self
                        .required(file, op, "angle")?
                        .trim()
                        .parse()
                        .map_err(|_| format!("{here}: a rotation's `angle` is not a number"))?;
                    if axis == DVec3::ZERO {
                        return Err(format!("{here}: a rotation about a zero axis"));
                    }
                    DMat4::from_axis_angle(axis.normalize(), angle.to_radians())
                }
                "matrix" => {
                    let v = self.required(file, op, "value")?;
                    match numbers(&v) {
                        Some(n) if n.len() == 16 => {
                            DMat4::from_cols_array(&n.try_into().unwrap_or([0.0; 16])).transpose()
                        }
                        Some(n) if n.len() == 9 => {
                            let r = |i: usize| DVec3::new(n[3 * i], n[3 * i + 1], n[3 * i + 2]);
                            DMat4::from_mat3(glam::DMat3::from_cols(r(0), r(1), r(2)).transpose())
                        }
                        _ => return Err(format!("{here}: a matrix of 16 (or 9) numbers, row by row")),
                    }
                }
                // `lookAt`: the spelling of files before version 2 (Veach's MIS scene), which
                // Mitsuba 3.7's parser no longer reads.
                "lookat" | "lookAt" => {
                    let point = |key: &str| -> Result<Option<DVec3>, String> {
                        match self.attribute(file, op, key)? {
                            None => Ok(None),
                            Some(v) => match numbers(&v).as_deref() {
                                Some([x, y, z]) => Ok(Some(DVec3::new(*x, *y, *z))),
                                _ => Err(format!("{here}: lookat `{key}` is not three numbers")),
                            },
                        }
                    };
                    let origin = point("origin")?.ok_or_else(|| format!("{here}: lookat has no `origin`"))?;
                    let target = point("target")?.ok_or_else(|| format!("{here}: lookat has no `target`"))?;
                    look_at(origin, target, point("up")?).ok_or_else(|| {
                        format!("{here}: lookat's origin is its target, or its up is along the view")
                    })?
                }
                other => return Err(format!("{here}: <{other}> is not a transform operation")),
            };
            m = step * m;
        }
        if !m.is_finite() {
            return Err(format!("{}: the transform is not finite", file.place(node)));
        }
        Ok(m)
    }
}

/// Mitsuba's look-at frame: columns x = normalize(up x dir), y = dir x x, z = dir, and the
/// origin; without an `up`, one not along the view.
pub fn look_at(origin: DVec3, target: DVec3, up: Option<DVec3>) -> Option<DMat4> {
    let dir = (target - origin).try_normalize()?;
    let up = match up {
        Some(u) => u,
        None => dir.any_orthonormal_vector(),
    };
    let left = up.cross(dir).try_normalize()?;
    let new_up = dir.cross(left);
    Some(DMat4::from_cols(left.extend(0.0), new_up.extend(0.0), dir.extend(0.0), origin.extend(1.0)))
}

/// The file being read.
struct File<'a, 'input> {
    path: &'a Path,
    doc: &'a roxmltree::Document<'input>,
    /// Older than version 2.0.0: camelCase property names are Mitsuba 3's snake_case.
    upgrade: bool,
}

impl File<'_, '_> {
    fn place(&self, node: roxmltree::Node) -> Place {
        Place { file: self.path.to_path_buf(), line: line(self.doc, node) }
    }

    /// A property name as Mitsuba 3 spells it: camelCase to snake_case for an old file.
    fn upgraded(&self, name: String) -> String {
        if !self.upgrade {
            return name;
        }
        let mut out = String::with_capacity(name.len() + 4);
        let mut previous: Option<char> = None;
        for c in name.chars() {
            if c.is_ascii_uppercase() {
                // An acronym (`intIOR`) is one word: an underscore only before its first letter.
                if previous.is_some_and(|p| !p.is_ascii_uppercase()) {
                    out.push('_');
                }
                out.push(c.to_ascii_lowercase());
            } else {
                out.push(c);
            }
            previous = Some(c);
        }
        out
    }
}

fn line(doc: &roxmltree::Document, node: roxmltree::Node) -> u32 {
    doc.text_pos_at(node.range().start).row
}

/// Numbers separated by commas and/or spaces.
fn numbers(s: &str) -> Option<Vec<f64>> {
    s.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(|t| t.parse().ok())
        .collect()
}

/// `raw` with each `$name` of `params` replaced, longest names first; `\$` is a dollar sign. A
/// `$name` no parameter defines is an error.
fn substitute(raw: &str, params: &HashMap<String, String>) -> Result<String, String> {
    if !raw.contains('$') {
        return Ok(raw.to_string());
    }
    let mut names: Vec<&String> = params.keys().collect();
    names.sort_by_key(|n| std::cmp::Reverse(n.len()));
    let (mut out, mut rest) = (String::new(), raw);
    while let Some(i) = rest.find('$') {
        if rest[..i].ends_with('\\') {
            out.push_str(&rest[..i - 1]);
            out.push('$');
            rest = &rest[i + 1..];
            continue;
        }
        out.push_str(&rest[..i]);
        let after = &rest[i + 1..];
        match names.iter().find(|n| after.starts_with(n.as_str())) {
            Some(n) => {
                out.push_str(&params[*n]);
                rest = &after[n.len()..];
            }
            None => {
                let word: String = after.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
                return Err(format!("`${word}` is not defined (no <default> or -D gives it)"));
            }
        }
    }
    out.push_str(rest);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).expect("write");
        p
    }

    #[test]
    fn defaults_overrides_and_substitution() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = write(
            dir.path(),
            "s.xml",
            r#"<scene version="3.0.0">
  <default name="spp" value="64"/>
  <default name="res" value="32"/>
  <default name="spp" value="8"/>
  <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
  <film type="hdrfilm"><integer name="width" value="$res$res"/><string name="cost" value="\$5"/></film>
</scene>"#,
        );
        let (root, _) = read(&p, &[("res".into(), "2".into())]).expect("reads");
        let kids: Vec<&Object> = root
            .children
            .iter()
            .filter_map(|c| if let Child::Object(o) = c { Some(o) } else { None })
            .collect();
        // The first default wins over a later one; -D wins over the default.
        assert_eq!(kids[0].get("sample_count").map(|p| &p.value), Some(&Value::Integer(64)));
        assert_eq!(kids[1].get("width").map(|p| &p.value), Some(&Value::Integer(22)));
        assert_eq!(kids[1].get("cost").map(|p| &p.value), Some(&Value::String("$5".into())));
        let bad =
            write(dir.path(), "b.xml", r#"<scene version="3.0.0"><float name="x" value="$nope"/></scene>"#);
        let e = read(&bad, &[]).expect_err("undefined");
        assert!(e.contains("b.xml:1") && e.contains("$nope"), "{e}");
    }

    #[test]
    fn transforms_apply_in_document_order() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = write(
            dir.path(),
            "t.xml",
            r#"<scene version="3.0.0"><shape type="sphere"><transform name="to_world">
  <scale value="2"/><translate x="1"/><rotate z="1" angle="90"/>
</transform></shape>
<shape type="cube"><transform name="to_world"><matrix value="1 0 0 5  0 1 0 6  0 0 1 7  0 0 0 1"/></transform></shape>
</scene>"#,
        );
        let (root, _) = read(&p, &[]).expect("reads");
        let m = |k: usize| match &root.children[k] {
            Child::Object(o) => match o.get("to_world").map(|p| &p.value) {
                Some(Value::Transform(m)) => *m,
                _ => panic!("no transform"),
            },
            _ => panic!("no object"),
        };
        // (1, 0, 0): scaled to (2, 0, 0), moved to (3, 0, 0), turned to (0, 3, 0).
        let q = m(0).transform_point3(DVec3::X);
        assert!((q - DVec3::new(0.0, 3.0, 0.0)).length() < 1e-12, "{q}");
        // Row major: the last column is the translation.
        assert_eq!(m(1).transform_point3(DVec3::ZERO), DVec3::new(5.0, 6.0, 7.0));
    }

    #[test]
    fn look_at_frame_is_mitsubas() {
        let m = look_at(DVec3::ZERO, DVec3::new(0.0, 0.0, -1.0), Some(DVec3::Y)).expect("frame");
        // z along the view, y up, x = up x dir (the viewer's left).
        assert_eq!(m.transform_vector3(DVec3::Z), DVec3::new(0.0, 0.0, -1.0));
        assert_eq!(m.transform_vector3(DVec3::Y), DVec3::Y);
        assert_eq!(m.transform_vector3(DVec3::X), DVec3::new(-1.0, 0.0, 0.0));
        assert!(look_at(DVec3::ZERO, DVec3::Y, Some(DVec3::Y)).is_none());
    }

    #[test]
    fn includes_splice_and_cycles_are_errors() {
        let dir = tempfile::tempdir().expect("tempdir");
        write(dir.path(), "part.xml", r#"<scene version="3.0.0"><bsdf type="diffuse" id="white"/></scene>"#);
        let p = write(
            dir.path(),
            "main.xml",
            r#"<scene version="3.0.0"><include filename="part.xml"/><shape type="cube"><ref id="white"/></shape></scene>"#,
        );
        let (root, _) = read(&p, &[]).expect("reads");
        assert!(matches!(&root.children[0], Child::Object(o) if o.id.as_deref() == Some("white")));
        assert!(
            matches!(&root.children[1], Child::Object(o) if matches!(&o.children[0], Child::Ref { id, .. } if id == "white"))
        );
        let a = write(dir.path(), "a.xml", r#"<scene version="3.0.0"><include filename="a.xml"/></scene>"#);
        let e = read(&a, &[]).expect_err("a cycle");
        assert!(e.contains("a cycle") && e.contains("a.xml:1"), "{e}");
    }

    #[test]
    fn old_files_get_snake_case_names_and_bad_xml_names_its_line() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = write(
            dir.path(),
            "old.xml",
            r#"<scene version="0.5.0"><bsdf type="dielectric"><float name="intIOR" value="1.5"/></bsdf>
<sensor type="perspective"><transform name="toWorld"><lookAt origin="0 0 0" target="0 0 -1" up="0 1 0"/></transform></sensor></scene>"#,
        );
        let (root, _) = read(&p, &[]).expect("reads");
        let names: Vec<String> = root
            .children
            .iter()
            .filter_map(|c| if let Child::Object(o) = c { Some(o.properties[0].name.clone()) } else { None })
            .collect();
        assert_eq!(names, ["int_ior", "to_world"]);
        let bad = write(dir.path(), "bad.xml", "<scene version=\"3.0.0\">\n<shape type=\"obj\">\n</scene>");
        let e = read(&bad, &[]).expect_err("unclosed");
        assert!(e.starts_with(&format!("{}:3", bad.display())), "{e}");
        let untyped = write(dir.path(), "u.xml", "<scene version=\"3.0.0\">\n<shape/>\n</scene>");
        assert!(read(&untyped, &[]).expect_err("no type").contains("u.xml:2"));
    }
}
