//! The triangle mesh type and its optional attribute layers.

use crate::error::MeshError;
use glam::{DVec2, DVec3};

/// A triangle surface mesh with optional per-vertex colours, texture coordinates and
/// materials. Positions are in millimetres by convention. Triangles are counter-clockwise
/// seen from outside (the side the normal points to).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions.
    pub positions: Vec<DVec3>,
    /// Vertex indices of each triangle.
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex RGB colour, if the file had one.
    pub vertex_colors: Option<Vec<[u8; 3]>>,
    /// Texture coordinates, indexed per triangle corner (OBJ allows seams).
    pub uv: Option<UvLayer>,
    /// Material library and per-triangle material assignment (OBJ `mtllib`/`usemtl`).
    pub materials: Option<MaterialLayer>,
}

/// Texture coordinates with their own index buffer: `triangles[t][k]` is the UV of corner
/// `k` of mesh triangle `t`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UvLayer {
    pub coords: Vec<DVec2>,
    pub triangles: Vec<[u32; 3]>,
}

/// Materials as an OBJ file names them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MaterialLayer {
    /// File names given by `mtllib`, relative to the mesh file, in order.
    pub libraries: Vec<String>,
    /// Material names given by `usemtl`, in order of first use.
    pub names: Vec<String>,
    /// Per triangle, the index into `names`, or `None` before the first `usemtl`.
    pub triangle_material: Vec<Option<u32>>,
}

impl TriMesh {
    /// A mesh with positions and triangles only.
    pub fn new(positions: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> TriMesh {
        TriMesh {
            positions,
            triangles,
            ..TriMesh::default()
        }
    }

    /// The mesh of `triangles` (indices into `positions`) with the vertices no triangle
    /// uses dropped and the rest renumbered in order of first use.
    pub fn from_used_vertices(positions: &[DVec3], triangles: &[[u32; 3]]) -> TriMesh {
        let (triangles, used) = crate::compact(triangles.iter().copied(), positions.len());
        let kept = used.iter().map(|&v| positions[v as usize]).collect();
        TriMesh::new(kept, triangles)
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The three corner positions of triangle `t`.
    #[inline]
    pub fn triangle_positions(&self, t: usize) -> [DVec3; 3] {
        let [a, b, c] = self.triangles[t];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Checks what every algorithm relies on: at least one triangle, finite coordinates,
    /// indices in range, no triangle repeating a vertex, and attribute layers of matching
    /// size. The first problem found is returned, naming the element.
    pub fn validate(&self) -> Result<(), MeshError> {
        if self.triangles.is_empty() {
            return Err(MeshError::Empty);
        }
        for (vertex, p) in self.positions.iter().enumerate() {
            if !p.is_finite() {
                return Err(MeshError::NonFiniteVertex {
                    vertex,
                    position: p.to_array(),
                });
            }
        }
        let vertex_count = self.positions.len();
        for (triangle, tri) in self.triangles.iter().enumerate() {
            for &index in tri {
                if index as usize >= vertex_count {
                    return Err(MeshError::IndexOutOfRange {
                        triangle,
                        index,
                        vertex_count,
                    });
                }
            }
            if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
                return Err(MeshError::RepeatedVertex {
                    triangle,
                    indices: *tri,
                });
            }
        }
        if let Some(colors) = &self.vertex_colors {
            check_size("vertex colour layer", colors.len(), vertex_count)?;
        }
        if let Some(uv) = &self.uv {
            check_size(
                "texture coordinate layer",
                uv.triangles.len(),
                self.triangles.len(),
            )?;
            let uv_count = uv.coords.len();
            for (triangle, tri) in uv.triangles.iter().enumerate() {
                if let Some(&index) = tri.iter().find(|&&i| i as usize >= uv_count) {
                    return Err(MeshError::IndexOutOfRange {
                        triangle,
                        index,
                        vertex_count: uv_count,
                    });
                }
            }
        }
        if let Some(materials) = &self.materials {
            check_size(
                "material assignment layer",
                materials.triangle_material.len(),
                self.triangles.len(),
            )?;
        }
        Ok(())
    }

    /// Indices of triangles whose area is at most `min_area` (mm²): slivers and
    /// collinear corners that carry no surface and break normals.
    pub fn degenerate_triangles(&self, min_area: f64) -> Vec<usize> {
        (0..self.triangles.len())
            .filter(|&t| {
                let [a, b, c] = self.triangle_positions(t);
                0.5 * (b - a).cross(c - a).length() <= min_area
            })
            .collect()
    }

    /// Indices of triangles on the same three vertices as an earlier one, in either
    /// orientation: a doubled face (an export that wrote the surface twice) makes every
    /// edge of it shared by four triangles, and paths across the surface go wrong.
    pub fn repeated_triangles(&self) -> Vec<usize> {
        let mut seen = std::collections::HashSet::with_capacity(self.triangles.len());
        (0..self.triangles.len())
            .filter(|&t| {
                let mut corners = self.triangles[t];
                corners.sort_unstable();
                !seen.insert(corners)
            })
            .collect()
    }

    /// Removes the given triangles (indices into `triangles`), keeping every vertex and
    /// all attribute layers consistent.
    pub fn remove_triangles(&mut self, remove: &[usize]) {
        if remove.is_empty() {
            return;
        }
        let mut keep = vec![true; self.triangles.len()];
        for &t in remove {
            keep[t] = false;
        }
        retain_by_mask(&mut self.triangles, &keep);
        if let Some(uv) = &mut self.uv {
            retain_by_mask(&mut uv.triangles, &keep);
        }
        if let Some(materials) = &mut self.materials {
            retain_by_mask(&mut materials.triangle_material, &keep);
        }
    }

    /// Applies `f` to every vertex position (e.g. a rigid transform).
    pub fn map_positions(&mut self, f: impl Fn(DVec3) -> DVec3) {
        for p in &mut self.positions {
            *p = f(*p);
        }
    }
}

fn check_size(layer: &'static str, found: usize, expected: usize) -> Result<(), MeshError> {
    if found == expected {
        Ok(())
    } else {
        Err(MeshError::AttributeSize {
            layer,
            found,
            expected,
        })
    }
}

fn retain_by_mask<T>(items: &mut Vec<T>, keep: &[bool]) {
    let mut index = 0;
    items.retain(|_| {
        let kept = keep[index];
        index += 1;
        kept
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> TriMesh {
        TriMesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    #[test]
    fn unused_vertices_are_dropped_and_the_rest_renumbered_in_order_of_use() {
        let positions: Vec<DVec3> = (0..5).map(|i| DVec3::new(i as f64, 0.0, 0.0)).collect();
        let mesh = TriMesh::from_used_vertices(&positions, &[[4, 2, 3], [3, 2, 0]]);
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [2, 1, 3]]);
        let xs: Vec<f64> = mesh.positions.iter().map(|p| p.x).collect();
        assert_eq!(xs, vec![4.0, 2.0, 3.0, 0.0]);
    }

    #[test]
    fn validate_names_the_bad_element() {
        assert!(quad().validate().is_ok());

        let mut nan = quad();
        nan.positions[2].y = f64::NAN;
        assert!(matches!(
            nan.validate(),
            Err(MeshError::NonFiniteVertex { vertex: 2, .. })
        ));

        let mut out_of_range = quad();
        out_of_range.triangles[1][2] = 9;
        assert!(matches!(
            out_of_range.validate(),
            Err(MeshError::IndexOutOfRange {
                triangle: 1,
                index: 9,
                vertex_count: 4
            })
        ));

        let mut repeated = quad();
        repeated.triangles[0] = [0, 1, 1];
        assert!(matches!(
            repeated.validate(),
            Err(MeshError::RepeatedVertex { triangle: 0, .. })
        ));

        assert!(matches!(
            TriMesh::default().validate(),
            Err(MeshError::Empty)
        ));
    }

    #[test]
    fn degenerate_triangles_are_found_and_removed() {
        let mut mesh = quad();
        mesh.positions.push(DVec3::new(2.0, 0.0, 0.0));
        mesh.triangles.push([0, 1, 4]); // collinear
        assert_eq!(mesh.degenerate_triangles(1e-12), vec![2]);
        mesh.remove_triangles(&[2]);
        assert_eq!(mesh.triangle_count(), 2);
    }

    /// The quad written twice, the second copy turned round and rotated in its corners:
    /// every copy found, the originals kept.
    #[test]
    fn repeated_triangles_are_found_in_either_orientation() {
        let mut mesh = quad();
        mesh.triangles.extend([[2, 1, 0], [3, 0, 2]]);
        assert_eq!(mesh.repeated_triangles(), vec![2, 3]);
        assert!(quad().repeated_triangles().is_empty());
    }
}
