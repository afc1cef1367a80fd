//! A scan's photograph (issue 25): the image its file names ([`mesh::io::texture_image_path`]),
//! decoded (the `image` crate: JPEG and PNG), and a moved scan written with it as OBJ +
//! MTL + image side by side, the convention ParaView and MeshLab read.
//!
//! A missing or unreadable image is a warning: the scan is shown in a uniform tone.

use crate::Progress;
use crate::staged::Staged;
use anyhow::{Context, Result};
use mesh::{MaterialLayer, TriMesh};
use std::io::Write;
use std::path::{Path, PathBuf};

/// A texture image and where it came from.
#[derive(Debug, Clone)]
pub struct ScanTexture {
    /// The image file.
    pub path: PathBuf,
    pub image: render::Texture,
}

/// The material name a textured OBJ written here uses.
const MATERIAL: &str = "skin";

/// The texture of the scan read from `path` as `mesh`: `None` when its file names none,
/// and `None` with a warning (saying why, and that the scan is shown in a uniform tone)
/// when the image is missing or unreadable or the mesh has no texture coordinates.
pub fn load_texture(path: &Path, mesh: &TriMesh, progress: &dyn Progress) -> Option<ScanTexture> {
    let fallback = "the scan is shown in a uniform skin tone";
    let image_path = match mesh::io::texture_image_path(path, mesh) {
        Ok(Some(image_path)) => image_path,
        Ok(None) => return None,
        Err(why) => {
            progress.warn(&format!("{}: {why}; {fallback}", path.display()));
            return None;
        }
    };
    if mesh.uv.is_none() {
        progress.warn(&format!(
            "{}: names the texture {} but has no texture coordinates; {fallback}",
            path.display(),
            image_path.display()
        ));
        return None;
    }
    match decode(&image_path) {
        Ok(image) => Some(ScanTexture {
            path: image_path,
            image,
        }),
        Err(why) => {
            progress.warn(&format!(
                "{}: its texture {} cannot be used ({why:#}); {fallback}",
                path.display(),
                image_path.display()
            ));
            None
        }
    }
}

/// The photograph's colour at every vertex of `mesh` (at the texture coordinates of the
/// vertex's first triangle corner; a vertex on a seam has the same skin on both sides;
/// a vertex in no triangle gets the first pixel's colour): the texture at the scan's own
/// resolution, for a viewer that colours vertices. `None` without texture coordinates.
pub fn vertex_colours(mesh: &TriMesh, texture: &render::Texture) -> Option<Vec<[u8; 3]>> {
    let uv = mesh.uv.as_ref()?;
    let mut at = vec![None; mesh.vertex_count()];
    for (corners, uv_corners) in mesh.triangles.iter().zip(&uv.triangles) {
        for (&v, &k) in corners.iter().zip(uv_corners) {
            let slot = &mut at[v as usize];
            if slot.is_none() {
                *slot = uv.coords.get(k as usize).copied();
            }
        }
    }
    Some(
        at.into_iter()
            .map(|uv| texture.colour_at(uv.unwrap_or(glam::DVec2::new(0.0, 1.0))))
            .collect(),
    )
}

/// Decodes a JPEG or PNG image to RGB pixels.
pub fn decode(path: &Path) -> Result<render::Texture> {
    let image = image::ImageReader::open(path)
        .with_context(|| format!("opening {}", path.display()))?
        .with_guessed_format()
        .with_context(|| format!("reading {}", path.display()))?
        .decode()
        .with_context(|| format!("decoding {}", path.display()))?
        .to_rgb8();
    let (width, height) = image.dimensions();
    let rgb = image.pixels().map(|p| p.0).collect();
    Ok(render::Texture::new(width, height, rgb)?)
}

/// Removes what [`stage_textured_obj`] wrote for `stem` in `folder` on an earlier run
/// (`<stem>.obj`, `<stem>.mtl`, `<stem>_texture.*`): called once a folder's new,
/// untextured content is in place, so no photograph of an earlier scan is left beside
/// it. Entries that cannot be removed are left (the folder's listing in `result.json`
/// says what belongs to it).
pub fn remove_textured_obj(folder: &Path, stem: &str) {
    let Ok(entries) = std::fs::read_dir(folder) else {
        return;
    };
    let image_prefix = format!("{stem}_texture.");
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name == format!("{stem}.obj")
            || name == format!("{stem}.mtl")
            || name.starts_with(&image_prefix)
        {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Stages `mesh` (with texture coordinates) as `<stem>.obj` in `folder` with `<stem>.mtl`
/// naming a copy of `texture`'s image file beside them; the names of the files staged.
pub fn stage_textured_obj(
    staged: &mut Staged,
    folder: &Path,
    stem: &str,
    mesh: &TriMesh,
    texture: &ScanTexture,
) -> Result<Vec<String>> {
    let image_name = format!(
        "{stem}_texture.{}",
        texture
            .path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("png")
    );
    let bytes = std::fs::read(&texture.path)
        .with_context(|| format!("reading the texture {}", texture.path.display()))?;
    staged.write(&folder.join(&image_name), |path| {
        mesh::io::write_atomically(path, |out| out.write_all(&bytes))
    })?;
    let mut names = stage_obj_wearing(staged, folder, stem, &image_name, mesh)?;
    names.push(image_name);
    Ok(names)
}

/// Stages `mesh` (with texture coordinates) as `<stem>.obj` in `folder` with `<stem>.mtl`
/// naming the image `image_name` (in `folder`, staged by the caller); the two names.
pub fn stage_obj_wearing(
    staged: &mut Staged,
    folder: &Path,
    stem: &str,
    image_name: &str,
    mesh: &TriMesh,
) -> Result<Vec<String>> {
    let (obj_name, mtl_name) = (format!("{stem}.obj"), format!("{stem}.mtl"));
    let mut textured = mesh.clone();
    textured.materials = Some(MaterialLayer {
        libraries: vec![mtl_name.clone()],
        names: vec![MATERIAL.into()],
        triangle_material: vec![Some(0); mesh.triangle_count()],
    });
    staged.write(&folder.join(&obj_name), |path| {
        mesh::io::write_obj(path, &textured)
    })?;
    staged.write(&folder.join(&mtl_name), |path| {
        mesh::io::write_atomically(path, |out| {
            writeln!(out, "newmtl {MATERIAL}\nKd 1 1 1\nmap_Kd {image_name}")
        })
    })?;
    Ok(vec![obj_name, mtl_name])
}
