//! Isosurface stuffing (Labelle and Shewchuk, "Isosurface Stuffing: Fast Tetrahedral
//! Meshes with Good Dihedral Angles", SIGGRAPH 2007) on a uniform BCC lattice.
//!
//! 1. Classify every lattice point inside or outside the surface (exact winding numbers
//!    along lattice lines, module `winding`).
//! 2. On every lattice edge between an inside and an outside point, find the cut point
//!    where the edge crosses the surface (ray cast; bisection as fallback).
//! 3. Warp: a cut point closer to an end than `α` times its edge's length
//!    ([`ALPHA_LONG`], [`ALPHA_SHORT`]) violates that end; violated lattice points move
//!    onto violating cut points and become surface vertices, outside points first (see
//!    `warp_targets`). Cut points on edges at a warped point are dropped.
//! 4. Fill every lattice tetrahedron by its stencil (module `stencils`).
//!
//! With the paper's parameters every output dihedral angle lies between about 10.7° and
//! 164.8°, whatever the surface (the tests measure 12.9° to 161.2° over hundreds of
//! rotated shapes and spacings). Interior lattice points are never moved: the interior
//! is the regular lattice.

use crate::error::TetraError;
use crate::lattice::{Lattice, LatticePoint};
use crate::stencils::{Sign, StencilContext, StencilVertex, fill};
use crate::surface::ClosedSurface;
use crate::tetmesh::TetMesh;
use crate::warp::{WarpCut, warp_targets};
use crate::winding::classify_line;
use glam::{DVec3, IVec3};
use rayon::prelude::*;

/// Warping threshold on long (axis-parallel) lattice edges, as a fraction of the edge
/// length (the paper's value for dihedral angles in [10.7°, 164.8°]).
pub const ALPHA_LONG: f64 = 0.24999;
/// Warping threshold on short (diagonal) lattice edges, as a fraction of the edge length.
pub const ALPHA_SHORT: f64 = 0.42978;

/// Lattice centres per parallel work item when filling tetrahedra.
const CENTRES_PER_TASK: usize = 256;

/// Where a lattice edge crosses the surface.
#[derive(Debug, Clone, Copy)]
struct Cut {
    /// [`Lattice::edge_id`] of the edge.
    edge: u64,
    inside: LatticePoint,
    outside: LatticePoint,
    /// Position on the surface (mm).
    position: DVec3,
    /// Distance from the inside end as a fraction of the edge length.
    fraction: f64,
}

/// Meshes the inside of `surface` with a BCC lattice of spacing `spacing_mm` (mm).
pub fn stuff(surface: &ClosedSurface, spacing_mm: f64) -> Result<TetMesh, TetraError> {
    let (lo, hi) = surface.bounds();
    let lattice = Lattice::around(lo, hi, spacing_mm)?;
    let inside = classify(surface, &lattice);
    let cuts = find_cuts(surface, &lattice, &inside);
    let warps = warp_targets(&cuts);
    let mut signs: Vec<Sign> = inside
        .par_iter()
        .map(|&i| if i { Sign::Inside } else { Sign::Outside })
        .collect();
    for &(point, _) in &warps {
        signs[point as usize] = Sign::Surface;
    }
    let stuffing = Stuffing {
        lattice: &lattice,
        cuts: &cuts,
        warps: &warps,
        signs: &signs,
    };
    let tets = stuffing.fill_lattice();
    if tets.is_empty() {
        return Err(TetraError::NoTetrahedra { spacing_mm });
    }
    Ok(stuffing.compact(tets))
}

/// Inside flags of every lattice point, by sweeping each lattice line along x.
fn classify(surface: &ClosedSurface, lattice: &Lattice) -> Vec<bool> {
    let mut inside = vec![false; lattice.point_count()];
    let (corners, centres) = inside.split_at_mut(lattice.corner_count());
    // Grid 0 (corners) has even doubled coordinates from 0, grid 1 (centres) odd from 1.
    for (flags, grid_offset, per_axis) in [
        (corners, 0, lattice.corners_per_axis()),
        (centres, 1, lattice.cubes()),
    ] {
        flags
            .par_chunks_mut(per_axis.x as usize)
            .enumerate()
            .for_each_init(Vec::new, |crossings, (row, line)| {
                let (j, k) = (
                    row as i32 % per_axis.y as i32,
                    row as i32 / per_axis.y as i32,
                );
                let doubled = |i: i32| IVec3::new(2 * i, 2 * j, 2 * k) + grid_offset;
                let start = lattice.position_of(doubled(0));
                surface.line_crossings(start.y, start.z, crossings);
                classify_line(
                    crossings,
                    |i| lattice.position_of(doubled(i as i32)).x,
                    line,
                );
            });
    }
    inside
}

/// The cut points of all lattice edges between an inside and an outside point, sorted by
/// edge id.
fn find_cuts(surface: &ClosedSurface, lattice: &Lattice, inside: &[bool]) -> Vec<Cut> {
    let mut edges: Vec<(u64, LatticePoint, LatticePoint)> = (0..lattice.point_count() as u32)
        .into_par_iter()
        .flat_map_iter(|index| {
            let p = lattice.point_at(index);
            let p_inside = inside[index as usize];
            lattice
                .forward_neighbours(p)
                .filter(move |q| inside[q.index as usize] != p_inside)
                .map(move |q| {
                    let (a, b) = if p_inside { (p, q) } else { (q, p) };
                    (Lattice::edge_id(p, q), a, b)
                })
        })
        .collect();
    edges.par_sort_unstable_by_key(|e| e.0);
    edges
        .par_iter()
        .map(|&(edge, inside, outside)| {
            let (a, b) = (lattice.position(inside), lattice.position(outside));
            let fraction = surface.segment_crossing(a, b);
            Cut {
                edge,
                inside,
                outside,
                position: a.lerp(b, fraction),
                fraction,
            }
        })
        .collect()
}

/// The warping rule's threshold for cut `cut`, as a fraction of its edge length.
fn alpha(cut: &Cut) -> f64 {
    if cut.inside.same_grid(cut.outside) {
        ALPHA_LONG
    } else {
        ALPHA_SHORT
    }
}

impl WarpCut for Cut {
    fn inside(&self) -> u32 {
        self.inside.index
    }

    fn outside(&self) -> u32 {
        self.outside.index
    }

    fn violation(&self, point: u32) -> Option<f64> {
        violation(self, point)
    }
}

/// Distance of `cut` from its end `point` in units of half a spacing, if it violates it.
fn violation(cut: &Cut, point: u32) -> Option<f64> {
    let length = if cut.inside.same_grid(cut.outside) {
        2.0
    } else {
        3f64.sqrt()
    };
    let fraction = if point == cut.inside.index {
        cut.fraction
    } else {
        1.0 - cut.fraction
    };
    (fraction < alpha(cut)).then_some(fraction * length)
}

/// The state of one stuffing run, as the stencils see it. Output vertex keys: lattice
/// point indices, then `point_count + cut index`.
struct Stuffing<'a> {
    lattice: &'a Lattice,
    cuts: &'a [Cut],
    warps: &'a [(u32, u32)],
    signs: &'a [Sign],
}

impl StencilContext for Stuffing<'_> {
    fn cut_key(&self, inside: LatticePoint, outside: LatticePoint) -> u32 {
        let edge = Lattice::edge_id(inside, outside);
        let cut = self
            .cuts
            .binary_search_by_key(&edge, |c| c.edge)
            .expect("an edge between an inside and an outside lattice point has a cut point");
        (self.signs.len() + cut) as u32
    }

    fn position(&self, key: u32) -> DVec3 {
        let point_count = self.signs.len() as u32;
        if key >= point_count {
            return self.cuts[(key - point_count) as usize].position;
        }
        match self.warps.binary_search_by_key(&key, |w| w.0) {
            Ok(w) => self.cuts[self.warps[w].1 as usize].position,
            Err(_) => self.lattice.position(self.lattice.point_at(key)),
        }
    }
}

impl Stuffing<'_> {
    /// The output tetrahedra (vertex keys) of every lattice tetrahedron.
    fn fill_lattice(&self) -> Vec<[u32; 4]> {
        let first_centre = self.lattice.corner_count();
        let centres = self.lattice.point_count() - first_centre;
        (0..centres.div_ceil(CENTRES_PER_TASK))
            .into_par_iter()
            .flat_map_iter(|task| {
                let start = first_centre + task * CENTRES_PER_TASK;
                let end = (start + CENTRES_PER_TASK).min(first_centre + centres);
                let mut lattice_tets = Vec::with_capacity(12);
                let mut out = Vec::new();
                for index in start..end {
                    let centre = self.lattice.point_at(index as u32);
                    self.lattice
                        .tetrahedra_from_centre(centre, &mut lattice_tets);
                    for tet in &lattice_tets {
                        let vertices = tet.map(|point| StencilVertex {
                            point,
                            sign: self.signs[point.index as usize],
                        });
                        if vertices.iter().any(|v| v.sign == Sign::Inside) {
                            fill(&vertices, self, &mut out);
                        }
                    }
                }
                out
            })
            .collect()
    }

    /// Numbers the used lattice points and cut points (lattice points first, each in key
    /// order) and builds the mesh.
    fn compact(&self, tets: Vec<[u32; 4]>) -> TetMesh {
        TetMesh::compacted(tets, self.signs.len() + self.cuts.len(), |key| {
            self.position(key)
        })
    }
}
