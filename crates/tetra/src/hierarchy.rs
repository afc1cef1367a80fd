//! A hierarchy of independent (not nested) tetrahedral meshes of one surface for the
//! multigrid solver: level 0 finest, each coarser level with twice the lattice spacing
//! and about 1/8 the elements.

use crate::error::TetraError;
use crate::stuffing::stuff;
use crate::surface::ClosedSurface;
use crate::tetmesh::TetMesh;

/// Lattice tetrahedra per cube of the BCC lattice: a tetrahedron has volume `h³ / 12`.
const TETS_PER_CUBE: f64 = 12.0;
/// A first guess within this relative distance of the requested element count is kept.
const ELEMENT_COUNT_SLACK: f64 = 0.05;

/// One level of the hierarchy.
#[derive(Debug, Clone)]
pub struct Level {
    /// Lattice spacing (mm).
    pub spacing_mm: f64,
    pub mesh: TetMesh,
}

/// Meshes of one surface at doubling spacings; `levels[0]` is the finest.
#[derive(Debug, Clone)]
pub struct Hierarchy {
    pub levels: Vec<Level>,
}

/// `levels` meshes of `surface`, level `l` with spacing `finest_spacing_mm · 2^l` (mm).
/// Fails if a level would have no tetrahedron (the shape is too small for its spacing).
pub fn build_hierarchy(
    surface: &ClosedSurface,
    finest_spacing_mm: f64,
    levels: usize,
) -> Result<Hierarchy, TetraError> {
    if levels == 0 {
        return Err(TetraError::ZeroCount {
            what: "the number of levels",
        });
    }
    let finest = Level {
        spacing_mm: finest_spacing_mm,
        mesh: stuff(surface, finest_spacing_mm)?,
    };
    coarsen(surface, finest, levels, None)
}

/// Like [`build_hierarchy`], with the finest spacing chosen by [`level_with_elements`].
pub fn build_hierarchy_with_elements(
    surface: &ClosedSurface,
    finest_elements: usize,
    levels: usize,
) -> Result<Hierarchy, TetraError> {
    hierarchy_with_elements(surface, finest_elements, levels, None)
}

/// Like [`build_hierarchy_with_elements`] with at most `max_levels` levels: coarsening
/// stops, without an error, before the first level that would have no tetrahedron or
/// fewer than `min_vertices` vertices (a multigrid's coarsest level should be small, but
/// not emptier than the shape allows).
pub fn build_hierarchy_down_to(
    surface: &ClosedSurface,
    finest_elements: usize,
    max_levels: usize,
    min_vertices: usize,
) -> Result<Hierarchy, TetraError> {
    hierarchy_with_elements(surface, finest_elements, max_levels, Some(min_vertices))
}

/// The finest level with about `finest_elements` tetrahedra, coarsened by [`coarsen`].
fn hierarchy_with_elements(
    surface: &ClosedSurface,
    finest_elements: usize,
    levels: usize,
    stop_below: Option<usize>,
) -> Result<Hierarchy, TetraError> {
    if levels == 0 {
        return Err(TetraError::ZeroCount {
            what: "the number of levels",
        });
    }
    coarsen(
        surface,
        level_with_elements(surface, finest_elements)?,
        levels,
        stop_below,
    )
}

/// Adds coarser levels to `finest` up to `levels` in all; with `stop_below` (a vertex
/// count) a level that is too coarse ends the hierarchy instead of failing it.
fn coarsen(
    surface: &ClosedSurface,
    finest: Level,
    levels: usize,
    stop_below: Option<usize>,
) -> Result<Hierarchy, TetraError> {
    let mut hierarchy = Hierarchy {
        levels: vec![finest],
    };
    for level in 1..levels {
        let spacing_mm = hierarchy.levels[0].spacing_mm * 2f64.powi(level as i32);
        let mesh = match (stuff(surface, spacing_mm), stop_below) {
            (Ok(mesh), Some(min)) if mesh.vertex_count() < min => break,
            (Err(TetraError::NoTetrahedra { .. }), Some(_)) => break,
            (result, _) => result?,
        };
        hierarchy.levels.push(Level { spacing_mm, mesh });
    }
    Ok(hierarchy)
}

/// A mesh of `surface` with about `elements` tetrahedra: the spacing is first estimated
/// from the volume (`12 V / h³` lattice tetrahedra), then corrected once by the cube
/// root of the ratio found; the closer of the two meshes is returned.
pub fn level_with_elements(surface: &ClosedSurface, elements: usize) -> Result<Level, TetraError> {
    if elements == 0 {
        return Err(TetraError::ZeroCount {
            what: "the number of elements",
        });
    }
    let target = elements as f64;
    let guess = (TETS_PER_CUBE * surface.volume_mm3() / target).cbrt();
    let first = Level {
        spacing_mm: guess,
        mesh: stuff(surface, guess)?,
    };
    let found = first.mesh.tet_count() as f64;
    if (found - target).abs() <= ELEMENT_COUNT_SLACK * target {
        return Ok(first);
    }
    let corrected = guess * (found / target).cbrt();
    let second = Level {
        spacing_mm: corrected,
        mesh: stuff(surface, corrected)?,
    };
    let miss = |level: &Level| (level.mesh.tet_count() as f64 - target).abs();
    Ok(if miss(&second) <= miss(&first) {
        second
    } else {
        first
    })
}
