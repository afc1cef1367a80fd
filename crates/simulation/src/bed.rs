//! The implant bed (paper V-A): the fill-in behind a breast shifted slightly backwards,
//! the surface "on top of which the implant is positioned", with a cylindrical
//! (Mercator-like) parameterisation.
//!
//! # Parameterisation
//! A chest is close to a cylinder about the body's long axis. [`ChestCylinder::fit`]
//! fits one cylinder to both fill-ins (axis along the anatomical frame's `y`, the
//! sternum's direction, a Kåsa least-squares circle across it). The fill-ins themselves
//! were built over a cylinder per breast about the chest's own axis, 11 to 20° from the
//! sternum's (anatomy's `fill_in`), so a fill-in is not exactly a graph over this one;
//! where it folds over seen from it, the bed is fitted to that fill-in alone. A point `p` gets cylindrical coordinates `(u, v, w)`:
//! `u = R θ` (arc length at the cylinder's radius `R`, `θ` the angle about the axis from
//! the anterior direction, growing towards the patient's left), `v` the height along
//! the axis, `w` the radial distance minus `R`. The bed is a graph `w = w_bed(u, v)` over
//! the `(u, v)` domain enclosed by the (shifted) cut curve: a point lies in front of the
//! bed when `w > w_bed(u, v)`. The implant's local coordinates `(x', y')` of a point are
//! a linear function of `(u - u_a, v - v_a)` whose matrix is the bed's tangent map at the
//! anchor `a`, so the parameterisation is isometric at the anchor and exact along the
//! cylinder's circles and generators (see [`crate::placement`]).
//!
//! # Shift
//! The bed is the fill-in moved backwards along its vertex normals by `shift_mm`
//! ([`DEFAULT_SHIFT_MM`] by default): the fill-in continues the skin of the chest, the
//! implant sits behind the gland on the pectoral fascia, a few millimetres deeper.

use crate::error::SimulationError;
use anatomy::AnatomicalFrame;
use anatomy::breast::Side;
use glam::{DMat2, DMat3, DVec2, DVec3};
use mesh::TriMesh;

/// Default backward shift of the implant bed behind the fill-in (mm): skin and
/// subcutaneous fat between the fill-in (at skin level, continuing the chest) and the
/// pectoral fascia on which a subglandular implant lies. "Slightly shifted" in the paper;
/// one third of the default rear-wall offset (15 mm, skin plus muscle).
pub const DEFAULT_SHIFT_MM: f64 = 5.0;

/// Radius used when the fill-ins are too flat for a circle fit (mm): practically a plane.
const FLAT_RADIUS_MM: f64 = 2000.0;

/// A cylinder about the body's long axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChestCylinder {
    /// A point on the axis (file frame, mm).
    pub centre: DVec3,
    /// Columns: angle zero (anterior), angle 90° (patient's left), the axis (up); unit.
    pub axes: DMat3,
    /// Radius (mm).
    pub radius_mm: f64,
}

impl ChestCylinder {
    /// The cylinder about the frame's vertical axis that best fits `points` (a Kåsa
    /// circle in the frame's transverse `x`-`z` plane). Falls back to a very large
    /// radius behind the points when the fit is ill-conditioned or the centre does not
    /// lie behind them.
    pub fn fit(points: &[DVec3], frame: &AnatomicalFrame) -> ChestCylinder {
        let up = frame.up();
        let left = frame.left();
        let anterior = frame.anterior();
        let n = points.len().max(1) as f64;
        let mean = points.iter().copied().sum::<DVec3>() / n;
        let across = |p: DVec3| DVec2::new((p - mean).dot(left), (p - mean).dot(anterior));
        let (mut m, mut rhs) = (DMat3::ZERO, DVec3::ZERO);
        for &p in points {
            let q = across(p);
            let row = DVec3::new(q.x, q.y, 1.0);
            m += DMat3::from_cols(row * row.x, row * row.y, row * row.z);
            rhs -= row * q.length_squared();
        }
        let scale = m.to_cols_array().iter().fold(0.0f64, |a, x| a.max(x.abs()));
        let fitted = (m.determinant().abs() > 1e-12 * scale.powi(3))
            .then(|| {
                let [d, e, f] = (m.inverse() * rhs).to_array();
                let c = DVec2::new(-0.5 * d, -0.5 * e);
                let r = (c.length_squared() - f).sqrt();
                // the centre must lie behind the points, the radius be sane
                (r.is_finite() && r < FLAT_RADIUS_MM && c.y < -0.3 * r).then_some((c, r))
            })
            .flatten();
        let (c, radius_mm) = fitted.unwrap_or((DVec2::new(0.0, -FLAT_RADIUS_MM), FLAT_RADIUS_MM));
        let centre = mean + left * c.x + anterior * c.y;
        ChestCylinder {
            centre,
            axes: DMat3::from_cols(anterior, left, up),
            radius_mm,
        }
    }

    /// Cylindrical coordinates `(u, v, w)` of `p` (mm): arc length at the radius from
    /// the anterior direction towards the patient's left, height, radial offset from the
    /// cylinder (positive outside).
    pub fn to_cylindrical(&self, p: DVec3) -> DVec3 {
        let q = self.axes.transpose() * (p - self.centre);
        let angle = q.y.atan2(q.x);
        DVec3::new(
            self.radius_mm * angle,
            q.z,
            q.truncate().length() - self.radius_mm,
        )
    }

    /// The outward radial direction at parameter `u` (unit, file frame).
    pub fn radial(&self, u: f64) -> DVec3 {
        let angle = u / self.radius_mm;
        self.axes.x_axis * angle.cos() + self.axes.y_axis * angle.sin()
    }
}

/// A point of the bed found from its parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BedPoint {
    /// Position (file frame, mm).
    pub position: DVec3,
    /// Unit normal, pointing anteriorly (away from the chest).
    pub normal: DVec3,
    /// Radial offset `w` of the bed at these parameters (mm).
    pub w: f64,
}

/// The foot of a point on the bed: where the bed's normal line through it starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Foot {
    /// Bed parameters of the foot.
    pub uv: DVec2,
    /// Signed distance of the point from the bed along `normal` (mm, positive in front).
    pub height_mm: f64,
    /// The bed's unit normal at the foot (anterior).
    pub normal: DVec3,
    /// The foot itself, the bed point at `uv` (file frame, mm).
    pub position: DVec3,
}

/// Most iterations of [`ImplantBed::foot`].
const FOOT_ITERATIONS: usize = 12;

/// Tangential distance at which [`ImplantBed::foot`] stops (mm).
const FOOT_TOLERANCE_MM: f64 = 1e-4;

/// The implant bed of one breast: the shifted fill-in over its `(u, v)` domain.
#[derive(Debug, Clone)]
pub struct ImplantBed {
    pub side: Side,
    /// Backward shift of the fill-in (mm).
    pub shift_mm: f64,
    pub cylinder: ChestCylinder,
    /// Shifted fill-in vertices (file frame, mm).
    pub positions: Vec<DVec3>,
    /// Unit vertex normals, anterior.
    pub normals: Vec<DVec3>,
    /// `(u, v)` of each vertex.
    pub uv: Vec<DVec2>,
    /// Radial offset `w` of each vertex.
    pub w: Vec<f64>,
    pub triangles: Vec<[u32; 3]>,
    /// The domain's boundary (the shifted cut curve) in `(u, v)`, in loop order.
    pub boundary: Vec<DVec2>,
    grid: UvGrid,
}

/// A uniform grid over the `(u, v)` domain listing the triangles overlapping each cell.
#[derive(Debug, Clone)]
struct UvGrid {
    lo: DVec2,
    cell: f64,
    nx: usize,
    ny: usize,
    start: Vec<u32>,
    items: Vec<u32>,
}

impl UvGrid {
    fn new(uv: &[DVec2], triangles: &[[u32; 3]]) -> UvGrid {
        let (lo, hi) = uv.iter().fold(
            (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
            |(a, b), &p| (a.min(p), b.max(p)),
        );
        let extent = (hi - lo).max(DVec2::splat(1e-9));
        let area = extent.x * extent.y;
        let cell = (2.0 * area / triangles.len().max(1) as f64)
            .sqrt()
            .max(extent.max_element() / 512.0);
        let nx = (extent.x / cell).floor() as usize + 1;
        let ny = (extent.y / cell).floor() as usize + 1;
        let mut grid = UvGrid {
            lo,
            cell,
            nx,
            ny,
            start: Vec::new(),
            items: Vec::new(),
        };
        let ranges: Vec<(usize, usize, usize, usize)> = triangles
            .iter()
            .map(|t| {
                let p = t.map(|v| uv[v as usize]);
                let a = p[0].min(p[1]).min(p[2]);
                let b = p[0].max(p[1]).max(p[2]);
                let (ax, ay) = grid.cell_of(a);
                let (bx, by) = grid.cell_of(b);
                (ax, ay, bx, by)
            })
            .collect();
        let mut count = vec![0u32; nx * ny + 1];
        for &(ax, ay, bx, by) in &ranges {
            for y in ay..=by {
                for x in ax..=bx {
                    count[x + nx * y + 1] += 1;
                }
            }
        }
        for i in 1..count.len() {
            count[i] += count[i - 1];
        }
        let mut fill = count.clone();
        let mut items = vec![0u32; count[nx * ny] as usize];
        for (t, &(ax, ay, bx, by)) in ranges.iter().enumerate() {
            for y in ay..=by {
                for x in ax..=bx {
                    let c = x + nx * y;
                    items[fill[c] as usize] = t as u32;
                    fill[c] += 1;
                }
            }
        }
        grid.start = count;
        grid.items = items;
        grid
    }

    fn cell_of(&self, p: DVec2) -> (usize, usize) {
        let q = ((p - self.lo) / self.cell).floor();
        (
            (q.x.max(0.0) as usize).min(self.nx - 1),
            (q.y.max(0.0) as usize).min(self.ny - 1),
        )
    }

    fn candidates(&self, p: DVec2) -> &[u32] {
        let q = (p - self.lo) / self.cell;
        if !(q.x >= 0.0 && q.y >= 0.0 && q.x < self.nx as f64 && q.y < self.ny as f64) {
            return &[];
        }
        let c = q.x as usize + self.nx * q.y as usize;
        &self.items[self.start[c] as usize..self.start[c + 1] as usize]
    }
}

/// Barycentric coordinates of `p` in the 2D triangle `t`.
fn barycentric2(t: [DVec2; 3], p: DVec2) -> [f64; 3] {
    let e1 = t[1] - t[0];
    let e2 = t[2] - t[0];
    let d = p - t[0];
    let det = e1.perp_dot(e2);
    let b1 = d.perp_dot(e2) / det;
    let b2 = e1.perp_dot(d) / det;
    [1.0 - b1 - b2, b1, b2]
}

/// Relative tolerance of the 2D point location (points on shared edges).
const UV_TOLERANCE: f64 = 1e-9;

impl ImplantBed {
    /// The bed of one breast: `fill` (its first `boundary_count` vertices the cut curve
    /// in loop order, the fill-in's convention) moved back by `shift_mm` along its
    /// vertex normals, parameterised over `cylinder`.
    ///
    /// Errors: a shift that is not finite, or a fill-in of which more than 5% of the
    /// triangles fold over in the cylinder's parameters (a few folded slivers along a
    /// steep lateral edge are tolerated: the point location then takes the triangle
    /// where the point lies deepest).
    pub fn new(
        side: Side,
        fill: &TriMesh,
        boundary_count: usize,
        cylinder: &ChestCylinder,
        shift_mm: f64,
    ) -> Result<ImplantBed, SimulationError> {
        let bad = |reason: String| SimulationError::BadFillIn { side, reason };
        if !shift_mm.is_finite() {
            return Err(SimulationError::BadPlacement {
                side,
                what: "shift_mm",
                value: shift_mm,
                expected: "a finite number of mm".into(),
            });
        }
        if fill.triangles.is_empty() || boundary_count < 3 {
            return Err(bad("it has no triangles".into()));
        }
        let (normals, positions) = shifted_surface(fill, cylinder, shift_mm);
        let cyl: Vec<DVec3> = positions
            .iter()
            .map(|p| cylinder.to_cylindrical(*p))
            .collect();
        let uv: Vec<DVec2> = cyl.iter().map(|c| DVec2::new(c.x, c.y)).collect();
        let w: Vec<f64> = cyl.iter().map(|c| c.z).collect();
        // consistent orientation in (u, v): all triangles one way (a graph)
        let flipped = folded_triangles(&uv, &fill.triangles)
            .iter()
            .filter(|&&f| f)
            .count();
        if flipped * 20 > fill.triangles.len() {
            return Err(bad(format!(
                "{flipped} of its {} triangles fold over seen from the body's axis",
                fill.triangles.len()
            )));
        }
        let grid = UvGrid::new(&uv, &fill.triangles);
        let boundary = uv[..boundary_count].to_vec();
        Ok(ImplantBed {
            side,
            shift_mm,
            cylinder: *cylinder,
            positions,
            normals,
            uv,
            w,
            triangles: fill.triangles.clone(),
            boundary,
            grid,
        })
    }

    /// The triangle holding parameters `p` and the barycentric coordinates there, or
    /// `None` outside the domain.
    pub fn locate(&self, p: DVec2) -> Option<(usize, [f64; 3])> {
        let mut best: Option<(usize, [f64; 3], f64)> = None;
        for &t in self.grid.candidates(p) {
            let tri = self.triangles[t as usize].map(|v| self.uv[v as usize]);
            let b = barycentric2(tri, p);
            let m = b[0].min(b[1]).min(b[2]);
            if m >= -UV_TOLERANCE && best.is_none_or(|(_, _, bm)| m > bm) {
                best = Some((t as usize, b, m));
            }
        }
        best.map(|(t, b, _)| (t, b))
    }

    /// The bed at parameters `p`: position, normal, radial offset. `None` outside.
    pub fn at(&self, p: DVec2) -> Option<BedPoint> {
        let (t, b) = self.locate(p)?;
        Some(self.interpolate(t, b))
    }

    /// The bed inside triangle `t` at barycentric coordinates `b`.
    pub fn interpolate(&self, t: usize, b: [f64; 3]) -> BedPoint {
        let tri = self.triangles[t];
        let mut position = DVec3::ZERO;
        let mut normal = DVec3::ZERO;
        let mut w = 0.0;
        for k in 0..3 {
            let v = tri[k] as usize;
            position += self.positions[v] * b[k];
            normal += self.normals[v] * b[k];
            w += self.w[v] * b[k];
        }
        BedPoint {
            position,
            normal: normal.normalize_or(self.cylinder.radial(self.uv[tri[0] as usize].x)),
            w,
        }
    }

    /// The foot of `p` (file frame, mm) on the bed: parameters `s` with
    /// `p = b(s) + h n(s)`, where `b` is the bed and `n` its interpolated normal, so that
    /// points are addressed by the same normal-offset coordinates the implant is laid
    /// off in. Iterates from `p`'s radial projection, moving `s` by the tangential part
    /// of `p - b(s)` through the bed's tangent map. `None` when the iteration walks off
    /// the domain (the normal line through `p` misses the bed).
    ///
    /// Why not the radial projection itself: where the bed is inclined against the
    /// cylinder's radius (the lower pole, the fold) two points on one bed normal get
    /// different radial parameters, hence different implant thicknesses, and a
    /// template laid off along the normals then folds elements over (measured: 40-60
    /// prescribed elements of the first tissue layer inverted on v02_average).
    pub fn foot(&self, p: DVec3) -> Option<Foot> {
        let c = self.cylinder.to_cylindrical(p);
        let mut uv = DVec2::new(c.x, c.y);
        for _ in 0..FOOT_ITERATIONS {
            let (t, b) = self.locate(uv)?;
            let at = self.interpolate(t, b);
            let d = p - at.position;
            let height_mm = d.dot(at.normal);
            let tangential = d - at.normal * height_mm;
            if tangential.length() <= FOOT_TOLERANCE_MM {
                return Some(Foot {
                    uv,
                    height_mm,
                    normal: at.normal,
                    position: at.position,
                });
            }
            // the triangle's tangent map J = [e1 e2] M⁻¹ from (u, v) to the bed
            let tri = self.triangles[t];
            let [pa, pb, pc] = tri.map(|v| self.positions[v as usize]);
            let [ua, ub, uc] = tri.map(|v| self.uv[v as usize]);
            let m = DMat2::from_cols(ub - ua, uc - ua);
            if m.determinant().abs() < 1e-12 {
                return None;
            }
            let m_inv = m.inverse();
            let (e1, e2) = (pb - pa, pc - pa);
            let ju = e1 * m_inv.x_axis.x + e2 * m_inv.x_axis.y;
            let jv = e1 * m_inv.y_axis.x + e2 * m_inv.y_axis.y;
            // least squares: JᵀJ Δ = Jᵀ t
            let jtj = DMat2::from_cols(
                DVec2::new(ju.dot(ju), jv.dot(ju)),
                DVec2::new(ju.dot(jv), jv.dot(jv)),
            );
            if jtj.determinant().abs() < 1e-12 {
                return None;
            }
            uv += jtj.inverse() * DVec2::new(ju.dot(tangential), jv.dot(tangential));
        }
        let (t, b) = self.locate(uv)?;
        let at = self.interpolate(t, b);
        Some(Foot {
            uv,
            height_mm: (p - at.position).dot(at.normal),
            normal: at.normal,
            position: at.position,
        })
    }

    /// Whether `p` lies inside the domain's boundary polygon (even-odd rule).
    pub fn contains(&self, p: DVec2) -> bool {
        let b = &self.boundary;
        let mut inside = false;
        let mut j = b.len() - 1;
        for i in 0..b.len() {
            let (a, c) = (b[i], b[j]);
            if (a.y > p.y) != (c.y > p.y) && p.x < (c.x - a.x) * (p.y - a.y) / (c.y - a.y) + a.x {
                inside = !inside;
            }
            j = i;
        }
        inside
    }

    /// Distance from `p` to the domain's boundary polygon (mm in parameters).
    pub fn distance_to_boundary(&self, p: DVec2) -> f64 {
        p.distance(self.nearest_on_boundary(p))
    }

    /// The point of the domain's boundary polygon nearest to `p`.
    pub fn nearest_on_boundary(&self, p: DVec2) -> DVec2 {
        let b = &self.boundary;
        let mut best = (f64::INFINITY, p);
        let mut j = b.len() - 1;
        for i in 0..b.len() {
            let (a, c) = (b[j], b[i]);
            let e = c - a;
            let t = ((p - a).dot(e) / e.length_squared().max(1e-300)).clamp(0.0, 1.0);
            let q = a + e * t;
            let d = p.distance_squared(q);
            if d < best.0 {
                best = (d, q);
            }
            j = i;
        }
        best.1
    }

    /// The same bed shifted `shift_mm` behind its surface instead (the surface's
    /// vertex normals are the bed's).
    pub fn shifted(&self, shift_mm: f64) -> Result<ImplantBed, SimulationError> {
        let surface = TriMesh::new(
            (self.positions.iter().zip(&self.normals))
                .map(|(p, n)| *p + *n * self.shift_mm)
                .collect(),
            self.triangles.clone(),
        );
        ImplantBed::new(
            self.side,
            &surface,
            self.boundary.len(),
            &self.cylinder,
            shift_mm,
        )
    }

    /// Area centroid of the domain in `(u, v)`.
    pub fn centroid_uv(&self) -> DVec2 {
        area_centroid(&self.uv, &self.triangles)
    }

    /// Area of the bed (mm², 3D).
    pub fn area_mm2(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let p = t.map(|v| self.positions[v as usize]);
                0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length()
            })
            .sum()
    }
}

/// The vertex normals of `surface`, smoothed ([`smoothed_normals`]) and turned outwards
/// (away from the cylinder's axis), and its vertices moved `shift_mm` back along them:
/// the bed's normals and positions.
pub fn shifted_surface(
    surface: &TriMesh,
    cylinder: &ChestCylinder,
    shift_mm: f64,
) -> (Vec<DVec3>, Vec<DVec3>) {
    let mut normals = smoothed_normals(surface, NORMAL_SMOOTHING_RADIUS_MM);
    let outward: f64 = (surface.positions.iter().zip(&normals))
        .map(|(p, n)| n.dot(cylinder.radial(cylinder.to_cylindrical(*p).x)))
        .sum();
    if outward < 0.0 {
        normals.iter_mut().for_each(|n| *n = -*n);
    }
    let positions = (surface.positions.iter().zip(&normals))
        .map(|(p, n)| *p - *n * shift_mm)
        .collect();
    (normals, positions)
}

/// Radius over which the bed's normals are averaged (mm): wider than the creases an
/// implant's thickness (up to some 50 mm) must not fold over, narrower than a breast.
const NORMAL_SMOOTHING_RADIUS_MM: f64 = 20.0;

/// Most passes of [`smoothed_normals`] (a bed of 0.5 mm edges would need 1,600).
const MAX_NORMAL_SMOOTHING_PASSES: usize = 400;

/// The vertex normals of `surface` averaged with their edge neighbours' (unit; uniform
/// weights) over about `radius_mm` (passes: the radius over the mean edge length,
/// squared, as a diffusion spreads): a bed offset along them by an implant's thickness
/// does not cross itself over creases narrower than that (the fold's crease, the valley
/// between the breasts), which raw vertex normals of a scan do. Measured in
/// `docs/dev/standing-frame.md` (placement on the fold).
fn smoothed_normals(surface: &TriMesh, radius_mm: f64) -> Vec<DVec3> {
    let mut normals = surface.vertex_normals();
    let mean_edge_mm = surface.mean_edge_length();
    if mean_edge_mm <= 0.0 {
        return normals;
    }
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); surface.positions.len()];
    for tri in &surface.triangles {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            neighbours[a as usize].push(b);
            neighbours[b as usize].push(a);
        }
    }
    let passes =
        ((radius_mm / mean_edge_mm).powi(2).ceil() as usize).min(MAX_NORMAL_SMOOTHING_PASSES);
    for _ in 0..passes {
        normals = (neighbours.iter().zip(&normals))
            .map(|(around, &n)| {
                let around_sum: DVec3 = around.iter().map(|&v| normals[v as usize]).sum();
                (around_sum + n * around.len() as f64).normalize_or(n)
            })
            .collect();
    }
    normals
}

/// Per triangle: whether it turns against the majority in `(u, v)` (folds over seen
/// from the cylinder's axis), or has no area there.
pub fn folded_triangles(uv: &[DVec2], triangles: &[[u32; 3]]) -> Vec<bool> {
    let signed: Vec<f64> = triangles
        .iter()
        .map(|t| {
            let p = t.map(|v| uv[v as usize]);
            (p[1] - p[0]).perp_dot(p[2] - p[0])
        })
        .collect();
    let total: f64 = signed.iter().sum();
    signed.iter().map(|&a| a * total <= 0.0).collect()
}

/// Area centroid of `triangles` over the 2D points `uv`.
pub fn area_centroid(uv: &[DVec2], triangles: &[[u32; 3]]) -> DVec2 {
    let mut sum = DVec2::ZERO;
    let mut area = 0.0;
    for t in triangles {
        let p = t.map(|v| uv[v as usize]);
        let a = 0.5 * (p[1] - p[0]).perp_dot(p[2] - p[0]).abs();
        sum += (p[0] + p[1] + p[2]) / 3.0 * a;
        area += a;
    }
    sum / area
}
