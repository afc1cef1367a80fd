//! Scans with a photograph (issue 25): the phantom's textured OBJ is read with its image,
//! its marks show in the rendered views where their 3D points project, a simulated scan
//! is written wearing it, and a missing image is a warning, not an error.

use anatomy::Up;
use glam::DVec2;
use phantom::PhantomParams;
use plan::Scan;
use plan::views::{ViewContent, standard_views};
use std::path::{Path, PathBuf};

mod warnings;
use warnings::Warnings;

fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mp-texture-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn textured_phantom(dir: &Path) -> phantom::Phantom {
    plan::demo::write_phantom(
        &PhantomParams::default(),
        &dir.join("scan.obj"),
        &dir.join("landmarks.json"),
    )
    .unwrap()
}

/// The darkest pixels' centroid within `radius_px` of `around` (pixels, y down): a mark
/// is dark blue on a light skin tone.
fn dark_centroid(png: &[u8], around: DVec2, radius_px: f64) -> Option<DVec2> {
    let image = image::load_from_memory(png).unwrap().to_rgb8();
    let mut sum = DVec2::ZERO;
    let mut count = 0.0;
    let r = radius_px.ceil() as i64;
    for dy in -r..=r {
        for dx in -r..=r {
            let (x, y) = (around.x.floor() as i64 + dx, around.y.floor() as i64 + dy);
            if x < 0 || y < 0 || x >= image.width() as i64 || y >= image.height() as i64 {
                continue;
            }
            let [red, _, blue] = image.get_pixel(x as u32, y as u32).0;
            // the mark's blue exceeds its red; skin, areola and shading do not
            if i32::from(blue) > i32::from(red) + 20 {
                sum += DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                count += 1.0;
            }
        }
    }
    (count > 0.0).then(|| sum / count)
}

#[test]
fn the_phantoms_marks_show_in_the_front_view_where_their_points_project() {
    let dir = folder("views");
    let phantom = textured_phantom(&dir);
    let warnings = Warnings::default();
    let scan = Scan::load(&dir.join("scan.obj"), &warnings).unwrap();
    let texture = scan.texture.as_ref().expect("the OBJ's photograph is read");
    assert_eq!(
        (texture.image.width(), texture.image.height()),
        (1024, 1024)
    );
    assert!(warnings.0.lock().unwrap().is_empty(), "{:?}", warnings.0);

    let content = ViewContent {
        texture: Some(&texture.image),
        ..ViewContent::default()
    };
    let front = standard_views(&scan.mesh, &phantom.landmarks, Up::FILE_VERTICAL, &content)
        .unwrap()
        .remove(0);
    // the marks' projections: the same cameras (framed by the scan alone) with the marks
    // as extra landmarks
    let mut with_marks = phantom.landmarks.clone();
    for (k, mark) in phantom.texture.marks.iter().enumerate() {
        with_marks.extra.insert(format!("mark{k:03}"), *mark);
    }
    let projected = standard_views(
        &scan.mesh,
        &with_marks,
        Up::FILE_VERTICAL,
        &ViewContent::default(),
    )
    .unwrap()
    .remove(0);
    // marks facing the camera: the front of the chest, away from the breasts' sides
    let mut checked = 0;
    for (k, mark) in phantom.texture.marks.iter().enumerate() {
        let facing = mark.x.abs() < 60.0 || mark.y < -280.0;
        let placement = projected
            .markers
            .iter()
            .find(|m| m.label == format!("mark{k:03}"))
            .unwrap();
        if !facing || !placement.pixel.is_finite() {
            continue;
        }
        // a 3 mm mark is some 5 pixels across at this scale; its centroid within 2 pixels
        let found = dark_centroid(&front.png, placement.pixel, 6.0)
            .unwrap_or_else(|| panic!("no mark near {:?} (mark {mark})", placement.pixel));
        assert!(
            found.distance(placement.pixel) <= 2.0,
            "mark {k} at {mark}: seen at {found}, projects to {}",
            placement.pixel
        );
        checked += 1;
    }
    assert!(checked >= 20, "only {checked} marks checked");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_simulated_scan_is_written_wearing_the_photograph_and_reopens_with_it() {
    let dir = folder("simulate");
    textured_phantom(&dir);
    let warnings = Warnings::default();
    let model_options = plan::model::ModelOptions {
        elements: 15_000,
        ..Default::default()
    };
    let marked = plan::MarkedScan::load(
        &dir.join("scan.obj"),
        &dir.join("landmarks.json"),
        None,
        &warnings,
    )
    .unwrap();
    let model = plan::model::build_model(&marked, &model_options, &warnings).unwrap();
    plan::model::write_model(&dir.join("model"), &model, &warnings).unwrap();
    let options = plan::simulate::SimulateOptions {
        left: Some(plan::simulate::ImplantRequest::new("catalog:R-MOD-100")),
        no_gravity: true,
        ..Default::default()
    };
    let report =
        plan::simulate::simulate(&dir.join("model"), &dir.join("sim"), &options, &warnings)
            .unwrap();
    for name in [
        "simulated_scan.obj",
        "simulated_scan.mtl",
        "simulated_scan_texture.png",
    ] {
        assert!(report.files.iter().any(|f| f == name), "{name}");
    }
    let reopened = Scan::load(&dir.join("sim/simulated_scan.obj"), &warnings).unwrap();
    let texture = reopened
        .texture
        .as_ref()
        .expect("the simulated OBJ wears the image");
    let original = plan::texture::decode(&dir.join("scan.png")).unwrap();
    assert_eq!(texture.image, original);
    // the same texture coordinates on the moved vertices
    let before = Scan::load(&dir.join("scan.obj"), &warnings).unwrap();
    assert_eq!(reopened.mesh.uv, before.mesh.uv);
    assert_ne!(reopened.mesh.positions, before.mesh.positions);
    // simulated again into the same folder without the photograph (its image gone): no
    // textured OBJ of the earlier run is left beside the new result
    std::fs::remove_file(dir.join("scan.png")).unwrap();
    let again = plan::simulate::simulate(&dir.join("model"), &dir.join("sim"), &options, &warnings)
        .unwrap();
    assert!(!again.files.iter().any(|f| f.ends_with(".obj")));
    for name in [
        "simulated_scan.obj",
        "simulated_scan.mtl",
        "simulated_scan_texture.png",
    ] {
        assert!(!dir.join("sim").join(name).exists(), "{name} left behind");
    }
    assert!(dir.join("sim/simulated_scan.ply").is_file());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_missing_or_broken_image_is_a_warning_and_the_scan_still_loads() {
    let dir = folder("missing");
    textured_phantom(&dir);
    std::fs::write(dir.join("scan.png"), b"not a png").unwrap();
    let warnings = Warnings::default();
    let scan = Scan::load(&dir.join("scan.obj"), &warnings).unwrap();
    assert!(scan.texture.is_none());
    let said = warnings.0.lock().unwrap().join("\n");
    assert!(
        said.contains("scan.png") && said.contains("uniform skin tone"),
        "{said}"
    );

    std::fs::remove_file(dir.join("scan.png")).unwrap();
    let warnings = Warnings::default();
    assert!(
        Scan::load(&dir.join("scan.obj"), &warnings)
            .unwrap()
            .texture
            .is_none()
    );
    assert!(warnings.0.lock().unwrap().join("\n").contains("scan.png"));
    let _ = std::fs::remove_dir_all(&dir);
}
