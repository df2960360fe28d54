//! A Mitsuba object's properties as a plugin reads them: each read marks its name, so that what
//! a plugin does not read becomes one note naming the file and line (Mitsuba itself refuses an
//! unread property; lightsplit renders on and says so).

use std::cell::RefCell;

use glam::{DMat4, DVec3};

use super::xml::{Object, Place, Value};

/// An object's properties and children, and which of them were read.
pub struct Props<'o> {
    pub object: &'o Object,
    read: RefCell<Vec<&'o str>>,
    /// An emitter's properties: a spectrum is radiance, not a reflectance (Mitsuba converts
    /// the two differently).
    emitter: bool,
}

impl<'o> Props<'o> {
    pub fn new(object: &'o Object) -> Self {
        Props { object, read: RefCell::new(Vec::new()), emitter: object.tag == "emitter" }
    }

    pub fn at(&self) -> &'o Place {
        &self.object.at
    }

    fn value(&self, name: &str) -> Option<(&'o Value, &'o Place)> {
        let p = self.object.properties.iter().find(|p| p.name == name)?;
        self.read.borrow_mut().push(&p.name);
        Some((&p.value, &p.at))
    }

    /// Marks `name` read without reading it (a property a plugin knows it does not need).
    pub fn skip(&self, name: &str) {
        let _ = self.value(name);
    }

    pub fn has(&self, name: &str) -> bool {
        self.object.properties.iter().any(|p| p.name == name)
    }

    pub fn float(&self, name: &str, default: f64) -> Result<f64, String> {
        match self.value(name) {
            None => Ok(default),
            Some((Value::Float(v), _)) => Ok(*v),
            Some((Value::Integer(v), _)) => Ok(*v as f64),
            Some((_, at)) => Err(format!("{at}: `{name}` is not a number")),
        }
    }

    pub fn integer(&self, name: &str, default: i64) -> Result<i64, String> {
        match self.value(name) {
            None => Ok(default),
            Some((Value::Integer(v), _)) => Ok(*v),
            Some((Value::Float(v), at)) if v.fract() != 0.0 => {
                Err(format!("{at}: `{name}` is not an integer"))
            }
            Some((Value::Float(v), _)) => Ok(*v as i64),
            Some((_, at)) => Err(format!("{at}: `{name}` is not an integer")),
        }
    }

    pub fn boolean(&self, name: &str, default: bool) -> Result<bool, String> {
        match self.value(name) {
            None => Ok(default),
            Some((Value::Boolean(v), _)) => Ok(*v),
            Some((_, at)) => Err(format!("{at}: `{name}` is not a boolean")),
        }
    }

    pub fn string(&self, name: &str) -> Result<Option<&'o str>, String> {
        match self.value(name) {
            None => Ok(None),
            Some((Value::String(v), _)) => Ok(Some(v.as_str())),
            Some((_, at)) => Err(format!("{at}: `{name}` is not a string")),
        }
    }

    pub fn point(&self, name: &str) -> Result<Option<DVec3>, String> {
        match self.value(name) {
            None => Ok(None),
            Some((Value::Point(v) | Value::Vector(v), _)) => Ok(Some(*v)),
            Some((_, at)) => Err(format!("{at}: `{name}` is not a point or vector")),
        }
    }

    pub fn transform(&self, name: &str) -> Result<DMat4, String> {
        match self.value(name) {
            None => Ok(DMat4::IDENTITY),
            Some((Value::Transform(m), _)) => Ok(*m),
            Some((_, at)) => Err(format!("{at}: `{name}` is not a transform")),
        }
    }

    /// A colour property (`rgb`, a constant `spectrum`, or a `float` as grey), if given as a
    /// value; a texture child is read by the caller.
    pub fn color(&self, name: &str) -> Result<Option<DVec3>, String> {
        match self.value(name) {
            None => Ok(None),
            Some((Value::Rgb(c), _)) => Ok(Some(*c)),
            Some((Value::Float(v), _)) => Ok(Some(DVec3::splat(*v))),
            Some((Value::Spectrum(pairs), at)) => {
                spectrum_rgb(pairs, self.emitter).map(Some).map_err(|e| format!("{at}: `{name}`: {e}"))
            }
            Some((_, at)) => Err(format!("{at}: `{name}` is not a colour")),
        }
    }

    /// The names of the properties nobody read.
    pub fn unread(&self) -> Vec<(&'o str, &'o Place)> {
        let read = self.read.borrow();
        self.object
            .properties
            .iter()
            .filter(|p| !read.contains(&p.name.as_str()))
            .map(|p| (p.name.as_str(), &p.at))
            .collect()
    }
}

/// A spectrum as Mitsuba's RGB variants read it (`src/core/properties.cpp`): a uniform one is
/// its value (an emitter's times the sRGB of XYZ (1, 1, 1), as the spectral variants would see
/// it); wavelength-value pairs are integrated, linearly between them, against the CIE 1931
/// curves at 1,000 steps from 360 to 830 nm (a reflectance lit by D65 and clamped to [0, 1], an
/// emitter's unweighted and clamped at 0) and turned from XYZ to linear sRGB.
pub fn spectrum_rgb(pairs: &[(f64, f64)], emitter: bool) -> Result<DVec3, String> {
    use super::cie;
    if let [(_, v)] = pairs {
        return Ok(if emitter { *v * xyz_to_srgb(DVec3::ONE) } else { DVec3::splat(*v) });
    }
    if pairs.windows(2).any(|w| w[1].0 <= w[0].0) {
        return Err("its wavelengths must increase".into());
    }
    let (first, last) = match (pairs.first(), pairs.last()) {
        (Some(f), Some(l)) => (f.0, l.0),
        _ => return Err("it is empty".into()),
    };
    let table = |w: f64, f: &dyn Fn(usize) -> DVec3| -> DVec3 {
        let x = ((w - cie::MIN) / 5.0).clamp(0.0, (cie::XYZ.len() - 1) as f64);
        let i = (x as usize).min(cie::XYZ.len() - 2);
        let t = x - i as f64;
        f(i) * (1.0 - t) + f(i + 1) * t
    };
    let steps = 1000;
    let mut xyz = DVec3::ZERO;
    for i in 0..steps {
        let w = cie::MIN + (i as f64 / (steps - 1) as f64) * (cie::MAX - cie::MIN);
        if w < first || w > last {
            continue;
        }
        let k = pairs.partition_point(|p| p.0 <= w).clamp(1, pairs.len() - 1) - 1;
        let ((w0, v0), (w1, v1)) = (pairs[k], pairs[k + 1]);
        let v = ((w - w1) * v0 + (w0 - w) * v1) / (w0 - w1);
        let cmf = table(w, &|i| DVec3::from_array(cie::XYZ[i]));
        let d65 = if emitter { 1.0 } else { table(w, &|i| DVec3::splat(cie::D65[i])).x };
        xyz += cmf * v * d65;
    }
    xyz *= (cie::MAX - cie::MIN) * cie::Y_NORMALIZATION / steps as f64;
    let rgb = xyz_to_srgb(xyz);
    Ok(if emitter { rgb.max(DVec3::ZERO) } else { rgb.clamp(DVec3::ZERO, DVec3::ONE) })
}

/// CIE XYZ to linear sRGB (Rec. 709 primaries, D65 white).
fn xyz_to_srgb(c: DVec3) -> DVec3 {
    DVec3::new(
        3.240479 * c.x - 1.537150 * c.y - 0.498535 * c.z,
        -0.969256 * c.x + 1.875991 * c.y + 0.041556 * c.z,
        0.055648 * c.x - 0.204043 * c.y + 1.057311 * c.z,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Mitsuba 3.9.1's own `spectrum_list_to_srgb` of the same lists (scalar_rgb).
    const MITSUBA_GREY: [f64; 3] = [0.776368, 0.779809, 0.776029];

    #[test]
    fn spectra_become_the_rgb_mitsuba_makes_of_them() {
        let light = [(400.0, 0.0), (500.0, 8.0), (600.0, 15.6), (700.0, 18.4)];
        let rgb = spectrum_rgb(&light, true).unwrap();
        let want = DVec3::new(20.7108, 10.8546, 2.77115);
        assert!(((rgb - want) / want).abs().max_element() < 1e-4, "{rgb}");
        let grey = [(400.0, 0.78), (500.0, 0.78), (600.0, 0.78), (700.0, 0.78)];
        let rgb = spectrum_rgb(&grey, false).unwrap();
        let want = DVec3::new(MITSUBA_GREY[0], MITSUBA_GREY[1], MITSUBA_GREY[2]);
        assert!((rgb - want).abs().max_element() < 1e-4, "{rgb}");
        assert_eq!(spectrum_rgb(&[(500.0, 0.5)], false).unwrap(), DVec3::splat(0.5));
        assert!(spectrum_rgb(&[(500.0, 1.0), (400.0, 1.0)], false).is_err());
    }
}
