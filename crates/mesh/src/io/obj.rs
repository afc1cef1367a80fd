//! Wavefront OBJ: polygon meshes with texture coordinates and materials, read and write.
//!
//! The parser is our own rather than `tobj`, so that every error names the line and the
//! problem ("line 1234: face refers to vertex 99999 but only 5000 vertices are defined");
//! `tobj`'s errors carry no line numbers. Reading a whole scan is a single pass over the
//! file in memory.
//!
//! Read: `v x y z [w]` (w ignored) or `v x y z r g b` (colour 0–1, kept as vertex colours;
//! vertices without one get white), `vt u [v [w]]`, `vn` (counted to check face
//! references; normals are recomputed, not kept), `f` with corners `v`, `v/vt`, `v//vn` or
//! `v/vt/vn`, negative (relative) indices, polygons fan-triangulated, `mtllib` and
//! `usemtl`, and lines continued with a trailing `\`. Everything after `#` is a comment;
//! `o`, `g`, `s`, `l`, `p` and unknown statements are ignored. Texture coordinates keep
//! their own indices (seams survive). If only some faces have texture coordinates, the
//! others get an extra coordinate (0, 0) appended to the layer; within one face, either
//! all corners have one or none.

use super::{ParseError, fan, parse_number, read_file, write_atomically};
use crate::error::MeshError;
use crate::geometry::check_position;
use crate::trimesh::{MaterialLayer, TriMesh, UvLayer};
use glam::{DVec2, DVec3};
use std::io::Write;
use std::path::Path;

/// Reads an OBJ file. Coordinates are checked to be finite; the rest of
/// [`TriMesh::validate`] is left to the caller (`read_mesh` runs it).
pub fn read_obj(path: &Path) -> Result<TriMesh, MeshError> {
    let data = read_file(path)?;
    parse(&String::from_utf8_lossy(&data)).map_err(|e| e.in_file(path))
}

/// Writes an OBJ file atomically: `mtllib`, `v` (with `r g b` in 0–1 when the mesh has
/// vertex colours), `vt`, and `f v/vt` (or `f v`) with a `usemtl` line wherever the
/// material changes. Numbers are printed in the shortest form that reads back exactly.
/// OBJ cannot switch back to "no material", so a triangle without one that follows
/// triangles with one keeps the previous material. Refuses a mesh that fails
/// [`TriMesh::validate`].
pub fn write_obj(path: &Path, mesh: &TriMesh) -> Result<(), MeshError> {
    mesh.validate()?;
    write_atomically(path, |out| {
        writeln!(out, "# written by mammaplan")?;
        let materials = mesh.materials.as_ref();
        if let Some(materials) = materials.filter(|m| !m.libraries.is_empty()) {
            writeln!(out, "mtllib {}", materials.libraries.join(" "))?;
        }
        for (vertex, p) in mesh.positions.iter().enumerate() {
            write!(out, "v {} {} {}", p.x, p.y, p.z)?;
            if let Some(colors) = &mesh.vertex_colors {
                let [r, g, b] = colors[vertex].map(|c| f64::from(c) / 255.0);
                write!(out, " {r} {g} {b}")?;
            }
            writeln!(out)?;
        }
        if let Some(uv) = &mesh.uv {
            for c in &uv.coords {
                writeln!(out, "vt {} {}", c.x, c.y)?;
            }
        }
        let mut current = None;
        for (t, triangle) in mesh.triangles.iter().enumerate() {
            if let Some(materials) = materials
                && let Some(material) = materials.triangle_material[t]
                && current != Some(material)
            {
                let name = materials.names.get(material as usize).ok_or_else(|| {
                    std::io::Error::other(format!(
                        "triangle {t} has material {material}, but only {} are named",
                        materials.names.len()
                    ))
                })?;
                writeln!(out, "usemtl {name}")?;
                current = Some(material);
            }
            let [a, b, c] = triangle.map(|v| v + 1);
            match &mesh.uv {
                Some(uv) => {
                    let [ta, tb, tc] = uv.triangles[t].map(|i| i + 1);
                    writeln!(out, "f {a}/{ta} {b}/{tb} {c}/{tc}")?;
                }
                None => writeln!(out, "f {a} {b} {c}")?,
            }
        }
        Ok(())
    })
}

/// Texture index of a corner without texture coordinates, until [`Builder::finish`].
const NO_UV: u32 = u32::MAX;

/// The mesh being read.
#[derive(Default)]
struct Builder {
    positions: Vec<DVec3>,
    /// Present once any vertex had a colour.
    colors: Option<Vec<[u8; 3]>>,
    uv_coords: Vec<DVec2>,
    normal_count: usize,
    triangles: Vec<[u32; 3]>,
    /// Per triangle, its texture indices ([`NO_UV`] if its face had none).
    uv_triangles: Vec<[u32; 3]>,
    any_uv: bool,
    libraries: Vec<String>,
    names: Vec<String>,
    material: Option<u32>,
    triangle_material: Vec<Option<u32>>,
    /// Scratch: (vertex, texture) index of each corner of the current face.
    corners: Vec<(u32, u32)>,
}

fn parse(text: &str) -> Result<TriMesh, ParseError> {
    let mut mesh = Builder::default();
    // A statement continued with `\` and the line it started on.
    let mut pending: Option<(usize, String)> = None;
    for (index, raw) in text.lines().enumerate() {
        let content = raw.split('#').next().unwrap_or_default().trim_end();
        if let Some(head) = content.strip_suffix('\\') {
            let (_, joined) = pending.get_or_insert_with(|| (index + 1, String::new()));
            joined.push_str(head);
            joined.push(' ');
            continue;
        }
        let (line, result) = match pending.take() {
            None => (index + 1, mesh.statement(content)),
            Some((line, mut joined)) => {
                joined.push_str(content);
                (line, mesh.statement(&joined))
            }
        };
        result.map_err(|message| ParseError::at(line, message))?;
    }
    if let Some((line, joined)) = pending {
        mesh.statement(&joined)
            .map_err(|message| ParseError::at(line, message))?;
    }
    Ok(mesh.finish())
}

impl Builder {
    fn statement(&mut self, statement: &str) -> Result<(), String> {
        let mut words = statement.split_ascii_whitespace();
        match words.next() {
            Some("v") => self.vertex(words),
            Some("vt") => {
                let mut uv = [0.0; 3];
                match numbers(words, &mut uv)? {
                    1..=3 if uv.iter().all(|c| c.is_finite()) => {
                        self.uv_coords.push(DVec2::new(uv[0], uv[1]));
                        Ok(())
                    }
                    1..=3 => Err("texture coordinate is not finite".to_owned()),
                    _ => Err("a texture coordinate needs 1 to 3 values".to_owned()),
                }
            }
            Some("vn") => {
                self.normal_count += 1;
                Ok(())
            }
            Some("f") => self.face(words),
            Some("mtllib") => {
                let mut named = false;
                for name in words {
                    named = true;
                    if !self.libraries.iter().any(|l| l == name) {
                        self.libraries.push(name.to_owned());
                    }
                }
                if named {
                    Ok(())
                } else {
                    Err("mtllib needs a file name".to_owned())
                }
            }
            Some("usemtl") => {
                let name = words.collect::<Vec<_>>().join(" ");
                if name.is_empty() {
                    return Err("usemtl needs a material name".to_owned());
                }
                let index = match self.names.iter().position(|n| *n == name) {
                    Some(index) => index,
                    None => {
                        self.names.push(name);
                        self.names.len() - 1
                    }
                };
                self.material = Some(index as u32);
                Ok(())
            }
            _ => Ok(()),
        }
    }

    fn vertex<'a>(&mut self, words: impl Iterator<Item = &'a str>) -> Result<(), String> {
        let mut values = [0.0; 6];
        let count = numbers(words, &mut values)?;
        let color = match count {
            3 | 4 => None,
            6 => Some([values[3], values[4], values[5]]),
            _ => {
                return Err(format!(
                    "a vertex needs 'x y z', 'x y z w' or 'x y z r g b', found {count} values"
                ));
            }
        };
        let position = DVec3::new(values[0], values[1], values[2]);
        check_position(position)
            .map_err(|what| format!("vertex {}: {what}", self.positions.len() + 1))?;
        const WHITE: [u8; 3] = [255; 3];
        match (color, &mut self.colors) {
            (Some(rgb), colors) => colors
                .get_or_insert_with(|| vec![WHITE; self.positions.len()])
                .push(rgb.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)),
            (None, Some(colors)) => colors.push(WHITE),
            (None, None) => {}
        }
        self.positions.push(position);
        Ok(())
    }

    fn face<'a>(&mut self, words: impl Iterator<Item = &'a str>) -> Result<(), String> {
        self.corners.clear();
        let mut textured = 0;
        for corner in words {
            let mut parts = corner.split('/');
            let (v, vt, vn) = (parts.next(), parts.next(), parts.next());
            if parts.next().is_some() {
                return Err(format!(
                    "'{corner}' is not a face corner (v, v/vt, v//vn or v/vt/vn)"
                ));
            }
            let vertex = resolve(
                v.unwrap_or_default(),
                self.positions.len(),
                ("vertex", "vertices"),
            )?;
            let texture = match vt.filter(|s| !s.is_empty()) {
                Some(vt) => {
                    textured += 1;
                    let coords = ("texture coordinate", "texture coordinates");
                    resolve(vt, self.uv_coords.len(), coords)?
                }
                None => NO_UV,
            };
            if let Some(vn) = vn.filter(|s| !s.is_empty()) {
                resolve(vn, self.normal_count, ("normal", "normals"))?;
            }
            self.corners.push((vertex, texture));
        }
        let count = self.corners.len();
        if count < 3 {
            return Err(format!(
                "face has {count} vertices (a face needs at least 3)"
            ));
        }
        if textured != 0 && textured != count {
            return Err(
                "some corners of this face have texture coordinates and others do not".to_owned(),
            );
        }
        self.any_uv |= textured != 0;
        for triangle in fan(count) {
            let corners = triangle.map(|k| self.corners[k]);
            self.triangles.push(corners.map(|(v, _)| v));
            self.uv_triangles.push(corners.map(|(_, t)| t));
            self.triangle_material.push(self.material);
        }
        Ok(())
    }

    fn finish(self) -> TriMesh {
        let uv = self.any_uv.then(|| {
            let mut coords = self.uv_coords;
            let fill = coords.len() as u32;
            let mut triangles = self.uv_triangles;
            let mut filled = false;
            for index in triangles.iter_mut().flatten().filter(|i| **i == NO_UV) {
                *index = fill;
                filled = true;
            }
            if filled {
                coords.push(DVec2::ZERO);
            }
            UvLayer { coords, triangles }
        });
        let materials =
            (!self.libraries.is_empty() || !self.names.is_empty()).then_some(MaterialLayer {
                libraries: self.libraries,
                names: self.names,
                triangle_material: self.triangle_material,
            });
        TriMesh {
            positions: self.positions,
            triangles: self.triangles,
            vertex_colors: self.colors,
            uv,
            materials,
        }
    }
}

/// Parses the numbers of a statement into `values`; returns how many there were.
fn numbers<'a>(words: impl Iterator<Item = &'a str>, values: &mut [f64]) -> Result<usize, String> {
    let (mut count, most) = (0, values.len());
    for word in words {
        let slot = values
            .get_mut(count)
            .ok_or_else(|| format!("too many values (at most {most})"))?;
        *slot = parse_number(word)?;
        count += 1;
    }
    Ok(count)
}

/// Turns a 1-based or negative (relative to the `defined` so far) OBJ index into a
/// 0-based one. `what` names the indexed thing, singular and plural.
fn resolve(word: &str, defined: usize, what: (&str, &str)) -> Result<u32, String> {
    let (one, many) = what;
    let index: i64 = word
        .parse()
        .map_err(|_| format!("'{word}' is not a {one} index"))?;
    let resolved = match index {
        0 => return Err(format!("{one} index 0 is invalid (OBJ indices start at 1)")),
        1.. => index - 1,
        _ => defined as i64 + index,
    };
    if resolved < 0 || resolved >= defined as i64 {
        return Err(format!(
            "face refers to {one} {index} but only {defined} {many} are defined"
        ));
    }
    Ok(resolved as u32)
}
