//! Lengths of the model that the finest mesh must resolve.

/// A length of the model that the finest mesh must resolve: `mm`, but never less than
/// `min_spacings` finest lattice spacings. Fixed in millimetres, so the default mesh and
/// a finer one solve the same problem and their difference is the discretisation's (a
/// length in spacings changed the problem with the mesh; docs/dev/discretisation.md).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResolvedLength {
    pub mm: f64,
    pub min_spacings: f64,
}

impl ResolvedLength {
    /// The length on a mesh of finest spacing `spacing_mm` (mm).
    pub fn on_mesh(self, spacing_mm: f64) -> f64 {
        self.mm.max(self.min_spacings * spacing_mm)
    }
}

#[cfg(test)]
mod tests {
    use crate::session::{
        DEFAULT_RIM_SMOOTHING, DEFAULT_SCAN_SMOOTHING, DEFAULT_TEMPLATE_LAYER, FOLD_TAPER,
        OUTSIDE_BLEND_RADIUS,
    };

    #[test]
    fn a_resolved_length_is_fixed_in_mm_until_the_mesh_is_too_coarse() {
        // The default mesh on the shared bodies has a spacing of 6.0-7.0 mm (7.04 on
        // s12, where the floor adds 0.04 mm to the layer), and four times the elements
        // 0.63 of it: both meshes use the same lengths.
        for spacing_mm in [3.0, 4.0, 6.0, 7.0] {
            assert_eq!(DEFAULT_RIM_SMOOTHING.on_mesh(spacing_mm), 14.0);
            assert_eq!(DEFAULT_TEMPLATE_LAYER.on_mesh(spacing_mm), 7.0);
            assert_eq!(DEFAULT_SCAN_SMOOTHING.on_mesh(spacing_mm), 3.5);
            assert_eq!(OUTSIDE_BLEND_RADIUS.on_mesh(spacing_mm), 7.0);
            assert_eq!(FOLD_TAPER.on_mesh(spacing_mm), 10.5);
        }
        // A draft mesh of 10 mm keeps two spacings, one and one and a half.
        assert_eq!(DEFAULT_RIM_SMOOTHING.on_mesh(10.0), 20.0);
        assert_eq!(DEFAULT_TEMPLATE_LAYER.on_mesh(10.0), 10.0);
        assert_eq!(DEFAULT_SCAN_SMOOTHING.on_mesh(10.0), 5.0);
        assert_eq!(OUTSIDE_BLEND_RADIUS.on_mesh(10.0), 10.0);
        assert_eq!(FOLD_TAPER.on_mesh(10.0), 15.0);
    }
}
