//! A procedural female torso surface scan, as a three-camera clinical scanner (cameras at
//! -30°, 0° and +30°) sees it: an open surface of the front and sides from just above
//! the sternal notch to below the navel, with clavicles, sternal notch, sternum,
//! xiphoid, costal margins, navel and two breasts with areolae, nipples and
//! inframammary fold creases. Breast size, ptosis, measurement noise, natural asymmetry
//! and what the cameras miss are adjustable; the result is deterministic for a given
//! seed.
//!
//! Alongside the mesh it returns its exact landmarks (paper Fig. 2; each is a vertex of
//! the mesh) and its true breast volumes (the volume between the breast skin and the
//! chest wall beneath it), so later stages of the pipeline can be checked.
//!
//! Frame (mm): x to the patient's left, y up, z anterior; the origin is the noise-free
//! sternal notch `Pj`. The surface is a tensor-product grid in azimuth (±110° from the
//! front) and height, so it is a single open, manifold, consistently outward-oriented
//! sheet.
//!
//! The seed decides only the measurement noise and which side is larger when
//! asymmetry is asked for; the anatomy is otherwise fixed by the parameters.
//!
//! With [`PhantomParams::occlusion`] (`mammaplan phantom --occlusion`) the scan fails as
//! real ones do: it keeps only the triangles one of the three cameras of a standing
//! clinical scan sees, as the shared zoo scans were made. The eyes stand 1 m from the
//! vertical axis through the chest at nipple height, at -30°, 0° and +30°, 11 cm below
//! nipple height (the zoo's); a triangle is seen when the ray from an eye to its centroid
//! meets no other part of the noise-free surface more than 2.5 mm before it and its
//! normal is within 75° of the direction to the eye. Single triangles missed between seen
//! ones are kept, spikes and pinched rim vertices removed, and only the largest connected
//! piece stays. The underside of a full or hanging breast, the skin of the lateral fold
//! hidden behind a large breast, the sides, the shoulder tops and the bottom of the
//! sternal notch come out missing: holes a model must reconstruct (10 to 20% of a large,
//! hanging breast's skin; under 1% of a small, firm one's). A landmark the cameras did not
//! see moves to the nearest seen vertex along the surface (a hidden fold point to where
//! the scanned fold stops, down the chest wall, not up onto the breast; the sternal notch
//! `Pj` some 5 mm off its deepest point). The true chest wall, the true breast volumes
//! and the whole noise-free skin ([`Phantom::full_skin`], with the correspondence of the
//! scan's vertices and triangles to it) stay as they are, so a reconstruction can be
//! measured against the truth.

mod breast;
mod grid;
mod noise;
mod occlusion;
mod shape;
mod surface;
mod texture;
mod torso;

pub use texture::{AREOLA_RADIUS_MM, MARK_RADIUS_MM, SkinTexture, TEXTURE_SIZE};

use anatomy::{LandmarkName, Landmarks};
use breast::{Breast, BreastShape};
use glam::DVec3;
use grid::Grid;
use mesh::{Topology, TriMesh};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::str::FromStr;
use surface::TorsoSurface;
use torso::{MID_CLAVICLE_X_MM, XIPHOID_HEIGHT_MM, base_point, clavicle_height};

/// Breast size.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Cup {
    /// About 210 ml per breast.
    Small,
    /// About 340 ml per breast.
    #[default]
    Medium,
    /// About 565 ml per breast.
    Large,
}

/// A cup name that is not `small`, `medium` or `large`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown cup size \"{0}\": expected small, medium or large")]
pub struct ParseCupError(String);

impl FromStr for Cup {
    type Err = ParseCupError;

    fn from_str(name: &str) -> Result<Cup, ParseCupError> {
        match name.trim().to_ascii_lowercase().as_str() {
            "small" => Ok(Cup::Small),
            "medium" => Ok(Cup::Medium),
            "large" => Ok(Cup::Large),
            _ => Err(ParseCupError(name.to_string())),
        }
    }
}

impl std::fmt::Display for Cup {
    /// The name [`Cup::from_str`] reads back: `small`, `medium` or `large`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Cup::Small => "small",
            Cup::Medium => "medium",
            Cup::Large => "large",
        })
    }
}

impl Cup {
    /// The breast of this cup size (mm).
    fn shape(self) -> BreastShape {
        match self {
            Cup::Small => BreastShape {
                projection_mm: 36.0,
                medial_mm: 56.0,
                lateral_mm: 76.0,
                upper_mm: 88.0,
                lower_mm: 54.0,
                areola_radius_mm: 17.0,
                nipple_height_mm: 5.5,
            },
            Cup::Medium => BreastShape {
                projection_mm: 46.0,
                medial_mm: 62.0,
                lateral_mm: 82.0,
                upper_mm: 92.0,
                lower_mm: 62.0,
                areola_radius_mm: 20.0,
                nipple_height_mm: 6.5,
            },
            Cup::Large => BreastShape {
                projection_mm: 60.0,
                medial_mm: 70.0,
                lateral_mm: 88.0,
                upper_mm: 96.0,
                lower_mm: 72.0,
                areola_radius_mm: 24.0,
                nipple_height_mm: 7.5,
            },
        }
    }
}

/// What to generate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhantomParams {
    pub cup: Cup,
    /// Breast ptosis, 0 = none .. 1 = marked (nipple near the fold level); clamped.
    pub ptosis: f64,
    /// Standard deviation of Gaussian measurement noise along the normals (mm); 0 = none.
    /// Damped where it would make the scan cross itself (the crease under a large,
    /// hanging breast).
    pub noise_mm: f64,
    /// Natural asymmetry, 0 = symmetric .. 1 = noticeable (one breast about 9% larger
    /// and its nipple 6 mm lower; the seed picks the side); clamped.
    pub asymmetry: f64,
    /// Seed of the noise and of the choice of the larger side.
    pub seed: u64,
    /// Remove what the three cameras of a standing clinical scan do not see (the
    /// underside of a full or hanging breast, the lateral fold), keeping the largest
    /// connected piece; see the crate docs.
    pub occlusion: bool,
}

impl Default for PhantomParams {
    /// Medium cup, mild ptosis, no noise, symmetric, seed 1, no occlusion.
    fn default() -> PhantomParams {
        PhantomParams {
            cup: Cup::Medium,
            ptosis: 0.3,
            noise_mm: 0.0,
            asymmetry: 0.0,
            seed: 1,
            occlusion: false,
        }
    }
}

impl std::fmt::Display for PhantomParams {
    /// One line naming every parameter, e.g.
    /// `cup=medium ptosis=0.3 noise_mm=0 asymmetry=0 seed=1 occlusion=false`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "cup={} ptosis={} noise_mm={} asymmetry={} seed={} occlusion={}",
            self.cup, self.ptosis, self.noise_mm, self.asymmetry, self.seed, self.occlusion
        )
    }
}

/// True breast volumes (cm³ = ml).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BreastVolumes {
    pub left: f64,
    pub right: f64,
}

/// A generated scan with its ground truth.
#[derive(Debug, Clone)]
pub struct Phantom {
    /// The scan surface (mm), open, outward oriented; with occlusion only the part the
    /// cameras saw.
    pub scan: TriMesh,
    /// The surface beneath the breasts, without them and without noise: the truth a
    /// fill-in should reproduce (mm). Same vertices and triangles as `full_skin`, equal
    /// to it away from the breasts.
    pub chest_wall: TriMesh,
    /// The whole skin without noise and without occlusion: the truth a reconstruction of
    /// unseen skin should reproduce (mm). Without occlusion it has the vertices and
    /// triangles of `scan` (equal to it but for the noise).
    pub full_skin: TriMesh,
    /// For each vertex of `scan`, the same vertex of `full_skin` and `chest_wall` (the
    /// identity without occlusion).
    pub full_vertex: Vec<u32>,
    /// For each triangle of `scan`, the same triangle of `full_skin` and `chest_wall`
    /// (the identity without occlusion).
    pub full_triangle: Vec<u32>,
    /// The twelve landmarks, each exactly at a vertex of `scan` (mm). With occlusion, a
    /// landmark the cameras did not see sits at the nearest seen vertex (along the
    /// surface), as on a real scan.
    pub landmarks: Landmarks,
    /// Volume between each breast's skin and the chest wall beneath it (ml).
    pub breast_volume_ml: BreastVolumes,
    /// The skin's photograph: a texture over the scan's vertices, with marks at known
    /// places.
    pub texture: SkinTexture,
}

/// Arc length along the chest from the midline to the nipple (mm, before ptosis).
const NIPPLE_ARC_MM: f64 = 88.0;
/// Height of the nipple below the sternal notch before ptosis (mm).
const NIPPLE_HEIGHT_MM: f64 = -160.0;
/// Downward shift of the skin per mm of breast projection at ptosis 1.
const PTOSIS_SAG: f64 = 0.75;
/// Footprint growth of the larger breast at asymmetry 1 (fraction).
const ASYMMETRY_FOOTPRINT: f64 = 0.025;
/// Projection growth of the larger breast at asymmetry 1 (fraction).
const ASYMMETRY_PROJECTION: f64 = 0.035;
/// Extra drop of the larger breast's nipple at asymmetry 1 (mm).
const ASYMMETRY_DROP_MM: f64 = 6.0;
/// Where the fold's medial end is taken, as a fraction of the footprint's medial extent:
/// beyond it the crease has faded out.
const FOLD_MEDIAL_END: f64 = -0.8;
/// Where the fold's lateral end is taken, as a fraction of the lateral extent: at the
/// footprint's lateral edge, level with the nipple, where the breast meets the chest
/// wall at the side (a surgeon's PSMFll), so the cut curve through it runs round the
/// whole breast.
const FOLD_LATERAL_END: f64 = 1.0;
/// Cells per side of the integration grid of the true breast volume (about 0.8 mm by
/// 0.9 mm for a medium cup; the error is below 0.01%).
const VOLUME_CELLS: usize = 200;

/// Generates the phantom scan, its landmarks and its true breast volumes.
pub fn generate(params: &PhantomParams) -> Phantom {
    let mut rng = Pcg64::seed_from_u64(params.seed);
    let left_larger = rng.random_bool(0.5);
    let surface = TorsoSurface::new(place_breasts(params, left_larger));

    let landmark_parameters = landmark_parameters(&surface);
    let grid = Grid::new(&surface, &landmark_parameters);
    let origin = surface.sample(0.0, 0.0).skin;
    let full_skin = grid.mesh(&surface, origin, |sample| sample.skin);
    let chest_wall = grid.mesh(&surface, origin, |sample| sample.wall);
    let mut scan = full_skin.clone();

    let noise_mm = if params.noise_mm > 0.0 && params.noise_mm.is_finite() {
        params.noise_mm
    } else {
        0.0
    };
    if noise_mm > 0.0 {
        noise::add_noise(&mut scan, &full_skin, noise_mm, &mut rng);
    }

    // Grid lines pass through every landmark, so each landmark is a vertex.
    let mut landmark_vertices = landmark_parameters.map(|(theta, h)| grid.nearest_vertex(theta, h));
    let (full_vertex, full_triangle) = if params.occlusion {
        let (seen, vertex_map, triangle_map, moved) =
            scanned_part(&full_skin, &scan, &landmark_vertices);
        scan = seen;
        landmark_vertices = moved;
        (vertex_map, triangle_map)
    } else {
        (
            (0..scan.vertex_count() as u32).collect(),
            (0..scan.triangle_count() as u32).collect(),
        )
    };
    let landmarks = Landmarks::new(|name| scan.positions[landmark_vertices[name as usize]]);
    let [left, right] = surface
        .breasts
        .map(|b| breast_volume_ml(&surface, &b, VOLUME_CELLS));
    let grid_uv = grid.uv();
    let texture = texture::paint(
        &surface,
        origin,
        [
            landmark_parameters[LandmarkName::Pnl as usize],
            landmark_parameters[LandmarkName::Pnr as usize],
        ],
        full_vertex.iter().map(|&v| grid_uv[v as usize]).collect(),
    );
    Phantom {
        texture,
        scan,
        chest_wall,
        full_skin,
        full_vertex,
        full_triangle,
        landmarks,
        breast_volume_ml: BreastVolumes { left, right },
    }
}

/// The part of `scan` the cameras see of the noise-free `full_skin` (same vertices and
/// triangles), aimed at the chest at the nipples' height: the mesh, for each of its
/// vertices and triangles the index in `scan`, and the vertices of the landmarks
/// (indices into `full_skin`'s vertices given) in the new mesh, each moved to the
/// nearest seen vertex along the surface where the cameras did not see it.
fn scanned_part(
    full_skin: &TriMesh,
    scan: &TriMesh,
    landmark_vertices: &[usize; 12],
) -> (TriMesh, Vec<u32>, Vec<u32>, [usize; 12]) {
    let nipple_height = 0.5
        * (full_skin.positions[landmark_vertices[LandmarkName::Pnl as usize]].y
            + full_skin.positions[landmark_vertices[LandmarkName::Pnr as usize]].y);
    let pj = full_skin.positions[landmark_vertices[LandmarkName::Pj as usize]];
    let target = DVec3::new(pj.x, nipple_height, pj.z + occlusion::TARGET_DEPTH_MM);
    let topology = Topology::new(full_skin);
    let keep = occlusion::scanned_triangles(full_skin, &topology, &occlusion::camera_eyes(target));
    let mut kept_vertex = vec![false; full_skin.vertex_count()];
    for (corners, _) in full_skin.triangles.iter().zip(&keep).filter(|(_, k)| **k) {
        for &v in corners {
            kept_vertex[v as usize] = true;
        }
    }
    let nearest =
        occlusion::nearest_kept_vertices(full_skin, &topology, &kept_vertex, landmark_vertices);
    let (mut seen, vertex_map, triangle_map) = occlusion::submesh(full_skin, &keep);
    for (position, &v) in seen.positions.iter_mut().zip(&vertex_map) {
        *position = scan.positions[v as usize];
    }
    let mut new_index = vec![u32::MAX; full_skin.vertex_count()];
    for (k, &v) in vertex_map.iter().enumerate() {
        new_index[v as usize] = k as u32;
    }
    // The largest piece holds the front of the chest, so every landmark reaches it.
    let moved = std::array::from_fn(|k| {
        let vertex = nearest[k].unwrap_or(landmark_vertices[k]);
        new_index[vertex] as usize
    });
    (seen, vertex_map, triangle_map, moved)
}

/// A value in `[0, 1]`; anything else (including NaN) is clamped, NaN to 0.
fn unit_interval(value: f64) -> f64 {
    if value.is_nan() {
        0.0
    } else {
        value.clamp(0.0, 1.0)
    }
}

/// Both breasts, left first, shaped and placed by the parameters.
fn place_breasts(params: &PhantomParams, left_larger: bool) -> [Breast; 2] {
    let asymmetry = unit_interval(params.asymmetry);
    let sag = PTOSIS_SAG * unit_interval(params.ptosis);
    let breast = |side: f64| {
        let larger = (side > 0.0) == left_larger;
        let growth = if larger { asymmetry } else { 0.0 };
        Breast {
            side,
            shape: params.cup.shape().scaled(
                1.0 + ASYMMETRY_FOOTPRINT * growth,
                1.0 + ASYMMETRY_PROJECTION * growth,
            ),
            center_arc_mm: NIPPLE_ARC_MM,
            center_height_mm: NIPPLE_HEIGHT_MM - ASYMMETRY_DROP_MM * growth,
            sag,
        }
    };
    [breast(1.0), breast(-1.0)]
}

/// Parameter points `(theta, h)` of the twelve landmarks, in [`LandmarkName::ALL`] order.
fn landmark_parameters(surface: &TorsoSurface) -> [(f64, f64); 12] {
    let clavicle_h = clavicle_height(MID_CLAVICLE_X_MM);
    let clavicle_theta = azimuth_at_x(MID_CLAVICLE_X_MM, clavicle_h);
    let on_breast = |index: usize, (s, t): (f64, f64)| {
        let breast = &surface.breasts[index];
        surface.footprint_parameters(breast, s, t)
    };
    let shape = |index: usize| surface.breasts[index].shape;
    LandmarkName::ALL.map(|name| match name {
        LandmarkName::Pj => (0.0, 0.0),
        LandmarkName::Pcl => (clavicle_theta, clavicle_h),
        LandmarkName::Pcr => (-clavicle_theta, clavicle_h),
        LandmarkName::Pnl => on_breast(0, (0.0, 0.0)),
        LandmarkName::Pnr => on_breast(1, (0.0, 0.0)),
        LandmarkName::PSMFl => on_breast(0, shape(0).fold_point(0.0)),
        LandmarkName::PSMFr => on_breast(1, shape(1).fold_point(0.0)),
        LandmarkName::PSMFml => on_breast(0, shape(0).fold_point(FOLD_MEDIAL_END)),
        LandmarkName::PSMFmr => on_breast(1, shape(1).fold_point(FOLD_MEDIAL_END)),
        LandmarkName::PSMFll => on_breast(0, shape(0).fold_point(FOLD_LATERAL_END)),
        LandmarkName::PSMFlr => on_breast(1, shape(1).fold_point(FOLD_LATERAL_END)),
        LandmarkName::Px => (0.0, XIPHOID_HEIGHT_MM),
    })
}

/// Azimuth (rad, positive) at which the trunk at height `h` reaches lateral distance
/// `x_mm` from the midline, by bisection.
fn azimuth_at_x(x_mm: f64, h: f64) -> f64 {
    let (mut low, mut high) = (0.0, std::f64::consts::FRAC_PI_2);
    for _ in 0..60 {
        let middle = 0.5 * (low + high);
        if base_point(middle, h).x < x_mm {
            low = middle;
        } else {
            high = middle;
        }
    }
    0.5 * (low + high)
}

/// Volume (ml) between the skin and the chest wall over `breast`'s footprint, from the
/// divergence theorem on a `cells` x `cells` triangulation of both surfaces; the two
/// coincide on the footprint's bounding rectangle, so the difference of their signed
/// volumes is the enclosed volume.
fn breast_volume_ml(surface: &TorsoSurface, breast: &Breast, cells: usize) -> f64 {
    let shape = &breast.shape;
    let (s0, s1) = (-shape.medial_mm, shape.lateral_mm);
    let (t0, t1) = (-shape.lower_mm, shape.upper_mm);
    let nodes = cells + 1;
    let mut skin = Vec::with_capacity(nodes * nodes);
    let mut wall = Vec::with_capacity(nodes * nodes);
    for j in 0..nodes {
        let t = t0 + (t1 - t0) * j as f64 / cells as f64;
        for i in 0..nodes {
            let s = s0 + (s1 - s0) * i as f64 / cells as f64;
            let (theta, h) = surface.footprint_parameters(breast, s, t);
            let sample = surface.sample(theta, h);
            skin.push(sample.skin);
            wall.push(sample.wall);
        }
    }
    let origin = wall[(nodes / 2) * nodes + nodes / 2];
    let six_volume = |points: &[DVec3]| -> f64 {
        let mut sum = 0.0;
        for j in 0..cells {
            for i in 0..cells {
                let a = points[j * nodes + i] - origin;
                let b = points[j * nodes + i + 1] - origin;
                let c = points[(j + 1) * nodes + i + 1] - origin;
                let d = points[(j + 1) * nodes + i] - origin;
                sum += a.dot(b.cross(c)) + a.dot(c.cross(d));
            }
        }
        sum
    };
    // s grows towards +x on the left breast and towards -x on the right one.
    breast.side * (six_volume(&skin) - six_volume(&wall)) / 6.0 / 1000.0
}

#[cfg(test)]
mod tests;
