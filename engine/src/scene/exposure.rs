//! Photos as cameras make them: each photo's exposure from its EXIF tags (exposure time,
//! f-number, ISO), so that photos taken at different exposures (a phone or a camera on auto)
//! land on one radiance scale. A pixel value is proportional to radiance · t · ISO / N²; each
//! photo is scaled by the median of that exposure over the views divided by its own, so the
//! scale stays that of a typical photo of the set. EXR photos carry no EXIF: they are taken as
//! radiance already, and a set that mixes photos with and without exposure tags is refused.

use std::path::Path;

use exif::{In, Tag, Value};

use super::files::{self, FileKind};
use super::View;
use crate::error::{Error, Result};

/// What a photo's EXIF says of its exposure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Exposure {
    /// Exposure time (s), f-number, ISO sensitivity (100 when the tag is absent).
    pub time_s: f64,
    pub f_number: f64,
    pub iso: f64,
}

impl Exposure {
    /// Relative exposure: t · ISO/100 / N².
    pub fn value(&self) -> f64 {
        self.time_s * self.iso / 100.0 / (self.f_number * self.f_number)
    }
}

fn rational(f: &exif::Field) -> Option<f64> {
    match &f.value {
        Value::Rational(v) => v.first().map(|r| r.to_f64()),
        Value::SRational(v) => v.first().map(|r| r.to_f64()),
        _ => None,
    }
}

/// The exposure of the photo at `path`: None when it has no EXIF or no exposure tags (EXR
/// files never do). A tag that is present but not a positive number is an error naming it.
pub fn read(path: &Path) -> Result<Option<Exposure>> {
    if super::image::is_exr(path) {
        return Ok(None);
    }
    let bytes = files::read(path, FileKind::Image)?;
    let exif = match exif::Reader::new().read_from_container(&mut std::io::Cursor::new(bytes)) {
        Ok(e) => e,
        Err(exif::Error::NotFound(_)) | Err(exif::Error::BlankValue(_)) => return Ok(None),
        Err(e) => {
            return Err(Error::input(
                path,
                format!("EXIF: {e} (remove the EXIF block, or repair it, to load this photo)"),
            ))
        }
    };
    let field = |t: Tag| exif.get_field(t, In::PRIMARY);
    let (Some(t), Some(n)) = (field(Tag::ExposureTime), field(Tag::FNumber)) else {
        return Ok(None);
    };
    let positive = |name: &str, f: &exif::Field, v: Option<f64>| match v {
        Some(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(Error::input(
            path,
            format!(
                "EXIF {name}: expected a positive number, found {}",
                f.display_value()
            ),
        )),
    };
    let iso = match field(Tag::PhotographicSensitivity) {
        Some(f) => positive(
            "PhotographicSensitivity (ISO)",
            f,
            f.value.get_uint(0).map(f64::from),
        )?,
        None => 100.0,
    };
    Ok(Some(Exposure {
        time_s: positive("ExposureTime", t, rational(t))?,
        f_number: positive("FNumber", n, rational(n))?,
        iso,
    }))
}

/// The factor each view's photo is multiplied by (all 1 when no photo has exposure tags).
pub fn scales(views: &[View]) -> Result<Vec<f32>> {
    let exposures = (views.iter())
        .map(|v| read(&v.image))
        .collect::<Result<Vec<_>>>()?;
    let with = exposures.iter().filter(|e| e.is_some()).count();
    if with == 0 {
        return Ok(vec![1.0; views.len()]);
    }
    if let Some(i) = exposures.iter().position(|e| e.is_none()) {
        let other = &views[exposures.iter().position(|e| e.is_some()).unwrap()].image;
        return Err(Error::input(
            &views[i].image,
            format!(
                "no EXIF exposure (ExposureTime, FNumber) while {with} of the {} photos have one ({} does): \
                 relit cannot put them on one scale; give every photo its EXIF or none",
                views.len(),
                other.display()
            ),
        ));
    }
    let values: Vec<f64> = exposures.iter().map(|e| e.unwrap().value()).collect();
    let mut sorted = values.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    Ok(values.iter().map(|v| (median / v) as f32).collect())
}
