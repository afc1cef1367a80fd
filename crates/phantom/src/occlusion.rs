//! What a standing three-camera clinical scanner sees of the phantom: the triangles at
//! least one camera sees, as the shared zoo scans were made (their `*_meta.json`
//! `cameras`), cleaned as a scanner's meshing leaves them and reduced to the largest
//! connected piece ([`scanned_triangles`]); and where a hidden landmark goes
//! ([`nearest_kept_vertices`]).
//!
//! The cameras stand on a circle of [`CAMERA_DISTANCE_MM`] around the vertical axis
//! through a target on the chest at nipple height, at [`CAMERA_AZIMUTHS_DEG`], their eyes
//! [`CAMERA_DROP_MM`] below the target. A triangle is seen by a camera when the ray
//! from the eye to its centroid meets no other part of the surface more than
//! [`DEPTH_TOLERANCE_MM`] before it (a depth test) and its normal is within
//! [`MAX_INCIDENCE_DEG`] of the direction to the eye (steeper skin returns no usable
//! depth).

use glam::DVec3;
use mesh::OrderedMm;
use mesh::topology::NO_TRIANGLE;
use mesh::{SurfaceIndex, Topology, TriMesh};
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// Azimuths of the cameras around the vertical axis (degrees; 0 is straight in front,
/// positive towards the patient's left).
pub const CAMERA_AZIMUTHS_DEG: [f64; 3] = [-30.0, 0.0, 30.0];
/// Horizontal distance of each eye from the vertical axis through the target (mm).
pub const CAMERA_DISTANCE_MM: f64 = 1000.0;
/// How far the eyes are below the target (mm): the zoo's cameras are 106-131 mm below
/// their target at nipple height, looking slightly up.
pub const CAMERA_DROP_MM: f64 = 110.0;
/// Depth of the target in front of the sternal notch (mm), as in the zoo (28-31 mm).
pub const TARGET_DEPTH_MM: f64 = 30.0;
/// Largest angle between a triangle's normal and the direction to the eye at which the
/// camera still measures it (degrees).
pub const MAX_INCIDENCE_DEG: f64 = 75.0;
/// A surface this much or less in front of a triangle does not hide it (mm): the depth
/// tolerance of the visibility test.
pub const DEPTH_TOLERANCE_MM: f64 = 2.5;

/// The eyes of the three cameras (mm) aimed at `target`.
pub fn camera_eyes(target: DVec3) -> [DVec3; 3] {
    CAMERA_AZIMUTHS_DEG.map(|azimuth| {
        let (sin, cos) = azimuth.to_radians().sin_cos();
        target
            + DVec3::new(
                CAMERA_DISTANCE_MM * sin,
                -CAMERA_DROP_MM,
                CAMERA_DISTANCE_MM * cos,
            )
    })
}

/// Per triangle of `surface`, whether at least one eye sees it (see the module docs).
/// Uses all available cores.
pub fn visible_triangles(surface: &TriMesh, eyes: &[DVec3]) -> Vec<bool> {
    let Some(index) = SurfaceIndex::new(surface) else {
        return Vec::new();
    };
    let min_cos = MAX_INCIDENCE_DEG.to_radians().cos();
    let seen = |t: usize| -> bool {
        let normal = surface.triangle_normal(t);
        let centroid = surface.triangle_positions(t).iter().sum::<DVec3>() / 3.0;
        eyes.iter().any(|&eye| {
            let to_eye = eye - centroid;
            let distance = to_eye.length();
            if normal.dot(to_eye) < min_cos * distance {
                return false;
            }
            let direction = -to_eye / distance;
            index
                .cast_ray(eye, direction, distance - DEPTH_TOLERANCE_MM)
                .is_none()
        })
    };
    let count = surface.triangle_count();
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .clamp(1, 16);
    let chunk = count.div_ceil(threads).max(1);
    let mut flags = vec![false; count];
    std::thread::scope(|scope| {
        for (k, part) in flags.chunks_mut(chunk).enumerate() {
            let seen = &seen;
            scope.spawn(move || {
                for (offset, flag) in part.iter_mut().enumerate() {
                    *flag = seen(k * chunk + offset);
                }
            });
        }
    });
    flags
}

/// The triangles of `surface` the cameras at `eyes` see, cleaned as a scanner's meshing
/// leaves them: single triangles missed between seen ones are kept (only their
/// centroids were tested), spikes (triangles held by one edge or none) and pinches (a
/// vertex joining two separate fans) are removed, and only the largest connected piece
/// is kept. The rims of the holes are then simple loops, as a real scan's are.
pub fn scanned_triangles(surface: &TriMesh, topology: &Topology, eyes: &[DVec3]) -> Vec<bool> {
    let mut keep = visible_triangles(surface, eyes);
    let dropouts: Vec<usize> = (0..keep.len())
        .filter(|&t| !keep[t] && kept_neighbours(topology, &keep, t) == 3)
        .collect();
    for t in dropouts {
        keep[t] = true;
    }
    while remove_spikes(topology, &mut keep) | remove_pinches(surface, topology, &mut keep) {}
    keep_largest_piece(surface, topology, &mut keep);
    keep
}

/// How many of the edge neighbours of triangle `t` are kept.
fn kept_neighbours(topology: &Topology, keep: &[bool], t: usize) -> usize {
    topology.triangle_neighbors[t]
        .iter()
        .filter(|&&n| n != NO_TRIANGLE && keep[n as usize])
        .count()
}

/// Removes, until none is left, kept triangles with at most one kept edge neighbour.
/// Returns whether any was removed.
fn remove_spikes(topology: &Topology, keep: &mut [bool]) -> bool {
    let mut stack: Vec<usize> = (0..keep.len())
        .filter(|&t| keep[t] && kept_neighbours(topology, keep, t) <= 1)
        .collect();
    let mut removed = false;
    while let Some(t) = stack.pop() {
        if !keep[t] || kept_neighbours(topology, keep, t) > 1 {
            continue;
        }
        keep[t] = false;
        removed = true;
        for &n in &topology.triangle_neighbors[t] {
            if n != NO_TRIANGLE && keep[n as usize] {
                stack.push(n as usize);
            }
        }
    }
    removed
}

/// At every vertex whose kept triangles form more than one fan (joined through edges at
/// the vertex), keeps only the fan of the largest area. Returns whether any triangle was
/// removed.
fn remove_pinches(surface: &TriMesh, topology: &Topology, keep: &mut [bool]) -> bool {
    let mut removed = false;
    let mut fans: Vec<(usize, usize)> = Vec::new();
    for v in 0..surface.vertex_count() {
        let around: Vec<usize> = topology
            .vertex_triangles(v)
            .iter()
            .map(|&t| t as usize)
            .filter(|&t| keep[t])
            .collect();
        if around.len() < 2 {
            continue;
        }
        // Fan index of each kept triangle around `v`, by flooding across edges at `v`.
        fans.clear();
        let mut count = 0;
        for &seed in &around {
            if fans.iter().any(|&(t, _)| t == seed) {
                continue;
            }
            let mut stack = vec![seed];
            fans.push((seed, count));
            while let Some(t) = stack.pop() {
                for (k, &n) in topology.triangle_neighbors[t].iter().enumerate() {
                    let corners = surface.triangles[t];
                    let at_v = corners[k] as usize == v || corners[(k + 1) % 3] as usize == v;
                    let n = n as usize;
                    if n as u32 != NO_TRIANGLE
                        && at_v
                        && keep[n]
                        && !fans.iter().any(|&(u, _)| u == n)
                    {
                        fans.push((n, count));
                        stack.push(n);
                    }
                }
            }
            count += 1;
        }
        if count < 2 {
            continue;
        }
        let mut area = vec![0.0; count];
        for &(t, fan) in &fans {
            area[fan] += surface.triangle_area(t);
        }
        let largest = (0..count)
            .max_by(|&a, &b| area[a].total_cmp(&area[b]))
            .unwrap_or(0);
        for &(t, fan) in &fans {
            if fan != largest {
                keep[t] = false;
                removed = true;
            }
        }
    }
    removed
}

/// Keeps, of the flagged triangles, only those of the largest piece connected through
/// shared edges (by area).
fn keep_largest_piece(surface: &TriMesh, topology: &Topology, keep: &mut [bool]) {
    let mut piece = vec![u32::MAX; keep.len()];
    let mut area = Vec::new();
    let mut stack = Vec::new();
    for seed in 0..keep.len() {
        if !keep[seed] || piece[seed] != u32::MAX {
            continue;
        }
        let index = area.len() as u32;
        let mut total = 0.0;
        piece[seed] = index;
        stack.push(seed);
        while let Some(t) = stack.pop() {
            total += surface.triangle_area(t);
            for &n in &topology.triangle_neighbors[t] {
                if n != NO_TRIANGLE && keep[n as usize] && piece[n as usize] == u32::MAX {
                    piece[n as usize] = index;
                    stack.push(n as usize);
                }
            }
        }
        area.push(total);
    }
    let Some(largest) = (0..area.len()).max_by(|&a, &b| area[a].total_cmp(&area[b])) else {
        return;
    };
    for (flag, &p) in keep.iter_mut().zip(&piece) {
        *flag = *flag && p == largest as u32;
    }
}

/// The flagged triangles of `mesh` as a mesh of their own with only the vertices they
/// use (both in their original order), with, for each new vertex and triangle, its
/// index in `mesh`.
pub fn submesh(mesh: &TriMesh, keep: &[bool]) -> (TriMesh, Vec<u32>, Vec<u32>) {
    let mut new_index = vec![u32::MAX; mesh.vertex_count()];
    for (t, corners) in mesh.triangles.iter().enumerate() {
        if keep[t] {
            for &v in corners {
                new_index[v as usize] = 0;
            }
        }
    }
    let mut vertex_map = Vec::new();
    for (v, index) in new_index.iter_mut().enumerate() {
        if *index == 0 {
            *index = vertex_map.len() as u32;
            vertex_map.push(v as u32);
        }
    }
    let triangle_map: Vec<u32> = (0..mesh.triangle_count() as u32)
        .filter(|&t| keep[t as usize])
        .collect();
    let triangles = triangle_map
        .iter()
        .map(|&t| mesh.triangles[t as usize].map(|v| new_index[v as usize]))
        .collect();
    let positions = vertex_map
        .iter()
        .map(|&v| mesh.positions[v as usize])
        .collect();
    (TriMesh::new(positions, triangles), vertex_map, triangle_map)
}

/// For each vertex in `from`, the vertex with `kept[v]` nearest to it along the edges of
/// `mesh` (the shortest path over the surface, so that a fold point hidden under a
/// hanging breast moves down the chest wall to where the scanned fold stops rather than
/// up across the hidden underside onto the breast); a kept vertex stays. `None` where no
/// kept vertex is connected to it.
pub fn nearest_kept_vertices(
    mesh: &TriMesh,
    topology: &Topology,
    kept: &[bool],
    from: &[usize],
) -> Vec<Option<usize>> {
    let mut distance = vec![f64::INFINITY; mesh.vertex_count()];
    let mut touched = Vec::new();
    from.iter()
        .map(|&start| {
            for v in touched.drain(..) {
                distance[v] = f64::INFINITY;
            }
            let mut queue = BinaryHeap::new();
            distance[start] = 0.0;
            touched.push(start);
            queue.push(Reverse((OrderedMm(0.0), start)));
            while let Some(Reverse((OrderedMm(d), v))) = queue.pop() {
                if d > distance[v] {
                    continue;
                }
                if kept[v] {
                    return Some(v);
                }
                for w in topology.vertex_neighbors(mesh, v) {
                    let w = w as usize;
                    let through = d + mesh.positions[v].distance(mesh.positions[w]);
                    if through < distance[w] {
                        distance[w] = through;
                        touched.push(w);
                        queue.push(Reverse((OrderedMm(through), w)));
                    }
                }
            }
            None
        })
        .collect()
}
