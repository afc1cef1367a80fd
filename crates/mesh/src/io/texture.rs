//! Where a mesh file names its texture image (issue 25): an OBJ's materials (`map_Kd` in
//! the `.mtl` libraries its `mtllib` names, paths relative to the library), a PLY's
//! `comment TextureFile` (relative to the PLY). Finding the file is this module's job;
//! decoding the image is the caller's.

use crate::trimesh::TriMesh;
use std::path::{Path, PathBuf};

/// The texture image a mesh file names, if any: for an OBJ, the `map_Kd` of the material
/// most of its triangles use (else the first `map_Kd` of its libraries); for a PLY, its
/// first `comment TextureFile`. `mesh` is the mesh read from `mesh_path`. The image need
/// not exist: the caller reports that.
///
/// Errors: a material library or PLY header that cannot be read, named with its path.
pub fn texture_image_path(mesh_path: &Path, mesh: &TriMesh) -> Result<Option<PathBuf>, String> {
    let folder = mesh_path.parent().unwrap_or(Path::new(""));
    let extension = mesh_path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match extension.as_deref() {
        Some("obj") => {
            let Some(materials) = &mesh.materials else {
                return Ok(None);
            };
            let mut maps = Vec::new();
            for library in &materials.libraries {
                let path = folder.join(library);
                let text = std::fs::read_to_string(&path).map_err(|e| {
                    format!("material library {} cannot be read: {e}", path.display())
                })?;
                let library_folder = path.parent().unwrap_or(Path::new(""));
                maps.extend(
                    diffuse_maps(&text)
                        .into_iter()
                        .map(|(name, file)| (name, library_folder.join(file))),
                );
            }
            let mut uses = vec![0usize; materials.names.len()];
            for m in materials.triangle_material.iter().flatten() {
                if let Some(count) = uses.get_mut(*m as usize) {
                    *count += 1;
                }
            }
            let most_used = (0..uses.len())
                .max_by_key(|&k| uses[k])
                .map(|k| materials.names[k].as_str());
            let chosen = maps
                .iter()
                .find(|(name, _)| Some(name.as_str()) == most_used)
                .or(maps.first());
            Ok(chosen.map(|(_, path)| path.clone()))
        }
        Some("ply") => {
            let header = ply_header(mesh_path)?;
            Ok(header
                .lines()
                .filter_map(|line| line.trim().strip_prefix("comment"))
                .filter_map(|rest| rest.trim().strip_prefix("TextureFile"))
                .map(str::trim)
                .find(|name| !name.is_empty())
                .map(|name| folder.join(name)))
        }
        _ => Ok(None),
    }
}

/// `(material, image file)` for every `map_Kd` of a material library's text. The file is
/// the statement's last word (options such as `-s 1 1 1` come before it; names with
/// spaces are not supported).
pub fn diffuse_maps(mtl: &str) -> Vec<(String, String)> {
    let mut current = String::new();
    let mut maps = Vec::new();
    for line in mtl.lines() {
        let line = line.split('#').next().unwrap_or_default().trim();
        let mut words = line.split_ascii_whitespace();
        match words.next() {
            Some("newmtl") => current = words.collect::<Vec<_>>().join(" "),
            Some(keyword) if keyword.eq_ignore_ascii_case("map_Kd") => {
                if let Some(file) = words.last() {
                    maps.push((current.clone(), file.to_string()));
                }
            }
            _ => {}
        }
    }
    maps
}

/// The text of a PLY file's header, up to `end_header`.
fn ply_header(path: &Path) -> Result<String, String> {
    use std::io::BufRead;
    let file =
        std::fs::File::open(path).map_err(|e| format!("{} cannot be read: {e}", path.display()))?;
    let mut header = String::new();
    for line in std::io::BufReader::new(file).split(b'\n') {
        let line = line.map_err(|e| format!("{} cannot be read: {e}", path.display()))?;
        let text = String::from_utf8_lossy(&line);
        header.push_str(&text);
        header.push('\n');
        if text.trim() == "end_header" {
            break;
        }
    }
    Ok(header)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trimesh::MaterialLayer;
    use glam::DVec3;

    #[test]
    fn the_last_word_of_map_kd_is_the_file_and_each_map_belongs_to_its_material() {
        let mtl = "# exported\nnewmtl skin\nKd 1 1 1\nmap_Kd -s 1 1 1 photo.jpg\n\n\
                   newmtl hair\nMAP_KD hair.png # comment\nnewmtl plain\nKd 0.5 0.5 0.5\n";
        assert_eq!(
            diffuse_maps(mtl),
            vec![
                ("skin".to_string(), "photo.jpg".to_string()),
                ("hair".to_string(), "hair.png".to_string())
            ]
        );
    }

    fn triangle() -> TriMesh {
        TriMesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::Y], vec![[0, 1, 2]])
    }

    #[test]
    fn an_obj_names_the_map_of_its_most_used_material_relative_to_the_library() {
        let folder = std::env::temp_dir().join(format!("mp-texture-{}", std::process::id()));
        std::fs::create_dir_all(folder.join("materials")).unwrap();
        std::fs::write(
            folder.join("materials/scan.mtl"),
            "newmtl other\nmap_Kd other.png\nnewmtl skin\nmap_Kd skin.jpg\n",
        )
        .unwrap();
        let mut mesh = triangle();
        mesh.materials = Some(MaterialLayer {
            libraries: vec!["materials/scan.mtl".into()],
            names: vec!["skin".into()],
            triangle_material: vec![Some(0)],
        });
        let found = texture_image_path(&folder.join("scan.obj"), &mesh).unwrap();
        assert_eq!(found, Some(folder.join("materials/skin.jpg")));
        // a missing library is an error naming it
        mesh.materials.as_mut().unwrap().libraries = vec!["gone.mtl".into()];
        let error = texture_image_path(&folder.join("scan.obj"), &mesh).unwrap_err();
        assert!(error.contains("gone.mtl"), "{error}");
        std::fs::remove_dir_all(&folder).ok();
    }

    #[test]
    fn a_ply_names_its_texture_in_a_header_comment() {
        let folder = std::env::temp_dir().join(format!("mp-texture-ply-{}", std::process::id()));
        std::fs::create_dir_all(&folder).unwrap();
        let path = folder.join("scan.ply");
        std::fs::write(
            &path,
            "ply\nformat ascii 1.0\ncomment made by a scanner\ncomment TextureFile scan_tex.png\n\
             element vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
             element face 1\nproperty list uchar int vertex_indices\nend_header\n\
             0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
        )
        .unwrap();
        let found = texture_image_path(&path, &triangle()).unwrap();
        assert_eq!(found, Some(folder.join("scan_tex.png")));
        std::fs::remove_dir_all(&folder).ok();
    }
}
