//! The level hierarchy and the element-count target.

mod common;

use glam::DVec3;
use tetra::{ClosedSurface, build_hierarchy, build_hierarchy_with_elements, level_with_elements};

fn breast_sized_ellipsoid() -> ClosedSurface {
    ClosedSurface::new(&common::ellipsoid(DVec3::new(125.0, 100.0, 50.0), 200, 100)).unwrap()
}

#[test]
fn levels_double_the_spacing_and_divide_the_elements_by_about_eight() {
    let surface = breast_sized_ellipsoid();
    let hierarchy = build_hierarchy(&surface, 5.0, 4).unwrap();
    assert_eq!(hierarchy.levels.len(), 4);
    for (l, level) in hierarchy.levels.iter().enumerate() {
        assert_eq!(level.spacing_mm, 5.0 * 2f64.powi(l as i32));
        level.mesh.validate().unwrap();
        let quality = level.mesh.quality();
        eprintln!(
            "level {l}: spacing {} mm, {} tets, {} nodes, dihedral {:.1}° to {:.1}°, volume {:.1} ml",
            level.spacing_mm,
            level.mesh.tet_count(),
            level.mesh.vertex_count(),
            quality.min_dihedral_deg,
            quality.max_dihedral_deg,
            level.mesh.volume_mm3() / 1000.0
        );
        assert!(quality.min_dihedral_deg >= 10.7);
    }
    for pair in hierarchy.levels.windows(2) {
        let ratio = pair[0].mesh.tet_count() as f64 / pair[1].mesh.tet_count() as f64;
        // Interior elements scale by 8; boundary layers by about 4.
        assert!((6.0..9.0).contains(&ratio), "ratio {ratio}");
    }
}

#[test]
fn element_count_target_is_met_within_twenty_percent() {
    let surface = breast_sized_ellipsoid();
    for target in [5_000, 15_000, 40_000, 60_000] {
        let level = level_with_elements(&surface, target).unwrap();
        let found = level.mesh.tet_count();
        let miss = (found as f64 - target as f64) / target as f64;
        eprintln!(
            "target {target}: spacing {:.3} mm, {found} tets ({:+.1} %)",
            level.spacing_mm,
            100.0 * miss
        );
        assert!(miss.abs() <= 0.2, "{target} -> {found}");
    }
    let hierarchy = build_hierarchy_with_elements(&surface, 20_000, 3).unwrap();
    assert_eq!(hierarchy.levels.len(), 3);
    let finest = hierarchy.levels[0].mesh.tet_count() as f64;
    assert!((finest / 20_000.0 - 1.0).abs() <= 0.2);
}

#[test]
fn a_level_too_coarse_for_the_shape_is_an_error() {
    let surface = ClosedSurface::new(&mesh::shapes::icosphere(10.0, 3)).unwrap();
    let message = build_hierarchy(&surface, 4.0, 6).err().unwrap().to_string();
    assert!(message.contains("leaves no tetrahedron"), "{message}");
    assert!(build_hierarchy(&surface, 4.0, 0).is_err());
    assert!(level_with_elements(&surface, 0).is_err());
}
