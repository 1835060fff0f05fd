//! Shading by a file scalar (`--shading intensity|classification`): LAS intensity and
//! classification, PCD intensity, read only when asked, turned into the cloud's colour, and
//! clear errors when the file has none or it is constant.
#![allow(clippy::unwrap_used)]

use std::path::Path;

use scenes::scalar::{class_colour, intensity_range};
use scenes::{NoProgress, Scalar, SceneSpec};

/// A LAS 1.2 file (point format 0, no RGB) of `n` points on a line with the given
/// intensities and classes.
fn write_las(path: &Path, intensity: &[u16], class: &[u8]) {
    let mut b = las::Builder::from((1, 2));
    b.transforms = las::Vector {
        x: las::Transform {
            scale: 0.001,
            offset: 0.0,
        },
        y: las::Transform {
            scale: 0.001,
            offset: 0.0,
        },
        z: las::Transform {
            scale: 0.001,
            offset: 0.0,
        },
    };
    let mut w = las::Writer::from_path(path, b.into_header().unwrap()).unwrap();
    for (i, (&v, &c)) in intensity.iter().zip(class).enumerate() {
        w.write_point(las::Point {
            x: i as f64 * 0.1,
            y: (i % 7) as f64 * 0.1,
            z: 0.0,
            intensity: v,
            classification: las::point::Classification::new(c).unwrap(),
            ..Default::default()
        })
        .unwrap();
    }
    w.close().unwrap();
}

fn load(path: &Path, field: Option<Scalar>) -> Result<scenes::PointCloud, scenes::SceneError> {
    SceneSpec::parse(&path.to_string_lossy(), None, 1)?
        .with_colour_from(field)
        .load(None, &NoProgress)
        .map(|l| l.cloud)
}

#[test]
fn las_intensity_and_classification_become_colours() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tile.las");
    let intensity: Vec<u16> = (0..300).map(|i| (i * 97 % 1000) as u16).collect();
    let class: Vec<u8> = (0..300).map(|i| [2u8, 5, 6][i % 3]).collect();
    write_las(&path, &intensity, &class);
    // Without --shading by a scalar, no colour column: nothing is read for it.
    assert!(load(&path, None).unwrap().colors().is_none());
    let c = load(&path, Some(Scalar::Intensity)).unwrap();
    let values: Vec<f32> = intensity.iter().map(|&v| v as f32).collect();
    let (lo, hi) = intensity_range(&values);
    for (got, &v) in c.colors().unwrap().iter().zip(&values) {
        let g = (((v - lo) / (hi - lo)).clamp(0.0, 1.0) * 255.0).round() as u8;
        assert_eq!(*got, [g, g, g]);
    }
    let c = load(&path, Some(Scalar::Classification)).unwrap();
    for (got, &k) in c.colors().unwrap().iter().zip(&class) {
        assert_eq!(*got, class_colour(k));
    }
    // The scalar is part of the scene's identity (cached builds and references).
    let spec = |f| {
        SceneSpec::parse(&path.to_string_lossy(), None, 1)
            .unwrap()
            .with_colour_from(f)
            .content_hash()
            .unwrap()
    };
    let hashes = [
        spec(None),
        spec(Some(Scalar::Intensity)),
        spec(Some(Scalar::Classification)),
    ];
    assert!(hashes[0] != hashes[1] && hashes[1] != hashes[2] && hashes[0] != hashes[2]);
}

#[test]
fn missing_or_constant_scalars_are_errors_naming_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("flat.las");
    write_las(&path, &[0; 50], &[1; 50]);
    for field in [Scalar::Intensity, Scalar::Classification] {
        let m = load(&path, Some(field)).unwrap_err().to_string();
        assert!(
            m.contains("flat.las") && m.contains(field.name()) && m.contains("nothing to shade"),
            "{m}"
        );
    }
    // A generated scene and a PLY have none.
    let m = SceneSpec::parse("statue:1000", None, 1)
        .unwrap()
        .with_colour_from(Some(Scalar::Intensity))
        .load(None, &NoProgress)
        .unwrap_err()
        .to_string();
    assert!(m.contains("no intensity"), "{m}");
    let ply = dir.path().join("p.ply");
    std::fs::write(
        &ply,
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
         property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n",
    )
    .unwrap();
    let m = load(&ply, Some(Scalar::Classification))
        .unwrap_err()
        .to_string();
    assert!(
        m.contains("p.ply") && m.contains("no classification") && m.contains("LAS"),
        "{m}"
    );
}

#[test]
fn pcd_intensity_field() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("i.pcd");
    let mut text = String::from(
        "VERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n\
         WIDTH 4\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA ascii\n",
    );
    text.push_str("0 0 0 0\n1 0 0 10\nnan nan nan 99\n0 1 0 20\n");
    std::fs::write(&path, text).unwrap();
    let p = scenes::pcd::read(&path).unwrap();
    // The NaN point is dropped with its intensity.
    assert_eq!(p.intensity.as_deref(), Some(&[0.0, 10.0, 20.0][..]));
    let c = load(&path, Some(Scalar::Intensity)).unwrap();
    let greys: Vec<u8> = c.colors().unwrap().iter().map(|c| c[0]).collect();
    assert_eq!(greys, vec![0, 128, 255]);
    assert!(
        load(&path, Some(Scalar::Classification))
            .unwrap_err()
            .to_string()
            .contains("no classification")
    );
}
