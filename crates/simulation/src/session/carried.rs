//! What the solve carries: the displacement to the scan (through the point map and its
//! smoothing, or their composition), the landmarks and cut curves riding on the scan,
//! and the breast volumes after it (over the chest wall, and over a fill-in rebuilt on
//! the moved cut curve as on a post-operative scan cut along it).

use super::*;

/// Spacing (mm) of the points along a cut curve that [`Simulation::control_points_moved_by`]
/// carries: the spline through them follows the carried curve closely, and a curve of
/// some 450 mm gets about 45 points.
pub const CARRIED_CONTROL_POINT_SPACING_MM: f64 = 10.0;

/// Points about `spacing_mm` apart along the closed polyline `loop_points` (mm), by arc
/// length from its first point: `round(length / spacing_mm)` of them, at least three.
pub(super) fn points_along_loop(loop_points: &[DVec3], spacing_mm: f64) -> Vec<DVec3> {
    let n = loop_points.len();
    let edge = |k: usize| (loop_points[k], loop_points[(k + 1) % n]);
    let length: f64 = (0..n).map(|k| edge(k).0.distance(edge(k).1)).sum();
    let count = ((length / spacing_mm).round() as usize).max(3);
    let step = length / count as f64;
    let mut points = Vec::with_capacity(count);
    let mut walked = 0.0;
    for k in 0..n {
        let (a, b) = edge(k);
        let edge_length = a.distance(b);
        while points.len() < count && walked + edge_length >= points.len() as f64 * step {
            let t = (points.len() as f64 * step - walked) / edge_length.max(f64::MIN_POSITIVE);
            points.push(a.lerp(b, t.clamp(0.0, 1.0)));
        }
        walked += edge_length;
    }
    points
}

/// Points located on the scan, carried by the scan's displacement: each point's foot
/// on its closest scan triangle (the triangle's vertices and the foot's barycentric
/// weights), so a point on the scan stays on the simulated scan.
#[derive(Debug, Clone)]
pub(super) struct ScanFeet(Vec<([u32; 3], [f64; 3])>);

impl ScanFeet {
    pub(super) fn locate(
        scan: &TriMesh,
        index: &mesh::SurfaceIndex,
        points: impl IntoIterator<Item = DVec3>,
    ) -> ScanFeet {
        ScanFeet(
            points
                .into_iter()
                .map(|p| {
                    let foot = index.closest_point(p);
                    (scan.triangles[foot.triangle], foot.barycentric)
                })
                .collect(),
        )
    }

    /// The displacement (mm) of the `k`-th point: the scan displacement
    /// `scan_displacements` interpolated at its foot.
    pub(super) fn displacement(&self, k: usize, scan_displacements: &[DVec3]) -> DVec3 {
        let (vertices, weights) = self.0[k];
        (0..3)
            .map(|c| scan_displacements[vertices[c] as usize] * weights[c])
            .sum()
    }

    /// `points` (the located ones, in order) moved by `scan_displacements`.
    pub(super) fn moved(&self, points: &[DVec3], scan_displacements: &[DVec3]) -> Vec<DVec3> {
        (points.iter().enumerate())
            .map(|(k, &p)| p + self.displacement(k, scan_displacements))
            .collect()
    }
}

/// `Σ (a - o)·((b - o) × (c - o)) / 6` and the first moment about `o` of a triangle soup
/// (a closed surface when combined with its complement).
fn volume_and_moment(mesh: &TriMesh, origin: DVec3) -> (f64, DVec3) {
    mesh.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| mesh.positions[v as usize] - origin);
            let v = a.dot(b.cross(c)) / 6.0;
            (v, (a + b + c) * (v / 4.0))
        })
        .fold((0.0, DVec3::ZERO), |(v, m), (dv, dm)| (v + dv, m + dm))
}

/// Volume (ml) and centre (mm) of the breast closed by a fill-in: `patch` outward, `fill`
/// facing the same way as the base (outward), so it enters reversed.
pub(super) fn closed_volume(patch: &TriMesh, fill: &TriMesh) -> (f64, DVec3) {
    let n = patch.positions.len().max(1) as f64;
    let origin = patch.positions.iter().copied().sum::<DVec3>() / n;
    let (vp, mp) = volume_and_moment(patch, origin);
    let (vf, mf) = volume_and_moment(fill, origin);
    let v = vp - vf;
    (v / 1000.0, origin + (mp - mf) / v)
}

/// `fill` (its first `rim.len()` vertices its boundary loop) with a strip of triangles
/// from that loop to `rim` (as many points, in the same order), oriented as `fill`: a
/// surface whose boundary is `rim`. `keys` number the loop's points (the base's vertex
/// numbers): each quadrilateral of the strip is split as [`swept_quad`] splits the
/// same edge, so it cancels exactly against the swept skin beside the loop.
fn with_rim(fill: &TriMesh, rim: &[DVec3], keys: &[u32]) -> TriMesh {
    let n = rim.len() as u32;
    let first_rim = fill.positions.len() as u32;
    // whether the fill runs along its loop 0 -> 1 (else 1 -> 0)
    let forward = fill
        .triangles
        .iter()
        .any(|t| (0..3).any(|k| t[k] == 0 && t[(k + 1) % 3] == 1));
    let mut triangles = fill.triangles.clone();
    for i in 0..n {
        let j = (i + 1) % n;
        let quad = swept_quad(
            [j, i],
            [first_rim + j, first_rim + i],
            keys[j as usize] < keys[i as usize],
        );
        triangles.extend(quad.map(|[a, b, c]| if forward { [a, b, c] } else { [a, c, b] }));
    }
    let positions = fill.positions.iter().chain(rim).copied().collect();
    TriMesh::new(positions, triangles)
}

/// Volume (ml) and centre (mm) of a closed outward triangle soup.
fn soup_volume(soup: &TriMesh) -> (f64, DVec3) {
    let n = soup.positions.len().max(1) as f64;
    let origin = soup.positions.iter().copied().sum::<DVec3>() / n;
    let (v, m) = volume_and_moment(soup, origin);
    (v / 1000.0, origin + m / v)
}

/// Two triangle soups as one.
fn joined(a: &TriMesh, b: &TriMesh) -> TriMesh {
    let offset = a.positions.len() as u32;
    let positions = a.positions.iter().chain(&b.positions).copied().collect();
    let triangles = (a.triangles.iter().copied())
        .chain(b.triangles.iter().map(|t| t.map(|v| v + offset)))
        .collect();
    TriMesh::new(positions, triangles)
}

/// The breast closed by a fill-in as one outward triangle soup: `patch` and the reversed
/// `fill` (as in [`closed_volume`]); the loop vertices appear twice, which the divergence
/// theorem does not mind.
fn closed_soup(patch: &TriMesh, fill: &TriMesh) -> TriMesh {
    let reversed = (fill.triangles.iter())
        .map(|&[a, b, c]| [a, c, b])
        .collect();
    joined(patch, &TriMesh::new(fill.positions.clone(), reversed))
}

impl Simulation {
    /// Where each scan vertex is now (same order and count as the scan).
    pub fn scan_positions(&self) -> Vec<DVec3> {
        match &self.scan_carry {
            Some(carry) => carry.positions(&self.scan_rest, &self.u),
            None => (self.scan_displacements().into_iter())
                .zip(&self.scan_rest)
                .map(|(d, p)| *p + d)
                .collect(),
        }
    }

    /// Where the simulated fold of `side` lies (mm, file frame): on the vertical plane
    /// through the native fold's lowest point (standing frame, within
    /// [`FOLD_SECTION_HALF_WIDTH_MM`]), the lowest scan vertex up to 60 mm below it that
    /// moved more than [`FOLD_MOVED_FORWARD_MM`] forward: the junction of the breast the
    /// implant pushes out and the chest that stays. `None` where nothing moved there.
    pub fn simulated_fold(&self, side: Side) -> Option<DVec3> {
        let native = self.frame.to_local(self.landmarks.get(fold_lowest(side)));
        let moved = self.scan_positions();
        self.scan_rest
            .iter()
            .zip(&moved)
            .filter_map(|(rest, now)| {
                let (a, b) = (self.frame.to_local(*rest), self.frame.to_local(*now));
                let on_section = (a.x - native.x).abs() <= FOLD_SECTION_HALF_WIDTH_MM
                    && a.y > native.y - 60.0
                    && a.y < native.y + 60.0;
                (on_section && b.z - a.z > FOLD_MOVED_FORWARD_MM).then_some((b.y, *now))
            })
            .min_by(|p, q| p.0.total_cmp(&q.0))
            .map(|(_, now)| now)
    }

    /// The displacement of each scan vertex (mm): the finest level's, smoothed over the
    /// scan ([`SimulationOptions::scan_smoothing_mm`]); through the composed map once
    /// [`Simulation::use_scan_carry`] has been given it (which differs from the two steps
    /// by thousandths of a millimetre).
    pub fn scan_displacements(&self) -> Vec<DVec3> {
        match &self.scan_carry {
            Some(carry) => carry.displacements(&self.u),
            None => {
                let mut d = self.scan_map.displacements(&self.u);
                self.scan_smoother.apply(&mut d);
                d
            }
        }
    }

    /// A job composing the map to the scan and its smoothing into one sparse map
    /// ([`ScanCarry`]) on one thread of its own, to run beside the solver: a second or
    /// more once per model, for a live view that carries every cycle to the scan (a few
    /// carries are quicker without it). Hand its result to [`Simulation::use_scan_carry`].
    pub fn scan_carry_job(&self) -> impl FnOnce() -> ScanCarry + Send + 'static {
        let map = self.scan_map.clone();
        let smoother = self.scan_smoother.clone();
        let node_count = self.finest.positions.len();
        let held_at_zero = self.never_moved.clone();
        let source = self.carry_source();
        move || {
            let compose = || ScanCarry::new(&map, &smoother, node_count, &held_at_zero, source);
            match rayon::ThreadPoolBuilder::new().num_threads(1).build() {
                Ok(pool) => pool.install(compose),
                Err(_) => compose(),
            }
        }
    }

    /// Carries to the scan through `carry` from now on; `false` (and nothing changes)
    /// unless this simulation's [`Simulation::scan_carry_job`] composed it.
    pub fn use_scan_carry(&mut self, carry: ScanCarry) -> bool {
        let fits = carry.len() == self.scan_rest.len()
            && carry.node_count() == self.finest.positions.len()
            && carry.source() == self.carry_source();
        if fits {
            self.scan_carry = Some(carry);
        }
        fits
    }

    /// Identifies what the composed carry depends on: the sizes, the vertices left out,
    /// the smoothing's and the blend's radii and the falloff.
    fn carry_source(&self) -> u64 {
        use std::hash::{Hash, Hasher};
        let mut hasher = std::collections::hash_map::DefaultHasher::new();
        (self.scan_rest.len(), self.finest.positions.len()).hash(&mut hasher);
        self.never_moved.hash(&mut hasher);
        let lengths = [
            self.scan_smoothing_mm(),
            OUTSIDE_BLEND_RADIUS.on_mesh(self.spacing_mm),
            self.options.falloff_mm,
        ];
        lengths.map(f64::to_bits).hash(&mut hasher);
        hasher.finish()
    }

    /// The locator the scan and every carried point are mapped with.
    pub fn field_locator(&self) -> FieldLocator<'_> {
        field_locator(&self.finest, self.spacing_mm).expect("checked when the session was built")
    }

    /// The radius of the smoothing over the scan (mm, [`SimulationOptions::scan_smoothing_mm`]
    /// resolved on the finest mesh).
    pub fn scan_smoothing_mm(&self) -> f64 {
        self.options.scan_smoothing_on_mesh(self.spacing_mm)
    }

    /// The displacement of any points (mm), mapped like the scan (slower: locates them).
    pub fn displacements_at(&self, points: &[DVec3]) -> Vec<DVec3> {
        PointMap::new(&self.field_locator(), points, self.options.falloff_mm).displacements(&self.u)
    }

    /// The landmarks moved with the tissue (required and extra points): each by the
    /// scan's displacement ([`Simulation::scan_displacements`]) at its foot on the scan,
    /// so a landmark on the scan stays on the simulated scan.
    pub fn landmarks(&self) -> Landmarks {
        self.landmarks_moved_by(&self.scan_displacements())
    }

    /// The landmarks moved by the scan displacement `scan_displacements` (mm, one per
    /// scan vertex, as [`Simulation::scan_displacements`] returns).
    pub fn landmarks_moved_by(&self, scan_displacements: &[DVec3]) -> Landmarks {
        let at_foot = |k: usize| self.landmark_feet.displacement(k, scan_displacements);
        let mut out = self.landmarks.clone();
        let mut k = 0;
        for name in LandmarkName::ALL {
            out.set(name, self.landmarks.get(name) + at_foot(k));
            k += 1;
        }
        for p in out.extra.values_mut() {
            *p += at_foot(k);
            k += 1;
        }
        out
    }

    /// Control points of the breast model's cut curves on the simulated scan: points
    /// along the curves every [`CARRIED_CONTROL_POINT_SPACING_MM`], moved by the scan
    /// displacement `scan_displacements` (as [`Simulation::landmarks_moved_by`]). A
    /// breast model of the simulated scan along them cuts the same breasts. The fold
    /// landmarks move with the tissue in front of the implant, so default control points
    /// derived afresh from the moved landmarks would cut the simulated breast elsewhere;
    /// and the model's own few control points, carried, would leave the spline between
    /// them to cut across the reshaped breast (on `pair1_pre` with R-MOD-90 the right
    /// breast cut along the six carried points measured 4.8% below the simulation's
    /// volume over a rebuilt fill-in ([`BreastVolume::volume_rebuilt_fill_ml`]), along
    /// points every 10 mm 2.9%, most of which is the smoothing of the scan's
    /// displacement: 1.7% without it).
    pub fn control_points_moved_by(&self, scan_displacements: &[DVec3]) -> ControlPoints {
        let [left, right] = Side::BOTH.map(|side| {
            let s = side as usize;
            self.control_point_feet[s].moved(&self.control_points[s], scan_displacements)
        });
        ControlPoints { left, right }
    }

    /// The breast volumes after the simulation (see [`BreastVolume`]). The first call
    /// locates the breast meshes in the finest level (a fraction of a second).
    pub fn breast_volumes(&mut self) -> [BreastVolume; 2] {
        let landmarks = self.landmarks();
        let Simulation {
            mesh_maps,
            finest,
            spacing_mm,
            options,
            base,
            sides,
            ..
        } = self;
        let maps = mesh_maps.get_or_insert_with(|| {
            let locator =
                field_locator(finest, *spacing_mm).expect("checked when the session was built");
            let map = |m: &TriMesh| PointMap::new(&locator, &m.positions, options.falloff_mm);
            MeshMaps {
                base: map(base),
                patches: [map(&sides[0].patch), map(&sides[1].patch)],
                fills: [map(&sides[0].fill), map(&sides[1].fill)],
            }
        });
        let u = &self.u;
        let moved = |mesh: &TriMesh, map: &PointMap| {
            TriMesh::new(map.moved(&mesh.positions, u), mesh.triangles.clone())
        };
        let base = moved(&self.base, &maps.base);
        let params = FillInParams {
            cylinder_axis: (self.options.fill_in.cylinder_axis).or(Some(self.frame.sternum())),
            ..self.options.fill_in
        };
        let mut out = Vec::with_capacity(2);
        for side in Side::BOTH {
            let s = side as usize;
            let data = &self.sides[s];
            let patch = moved(&data.patch, &maps.patches[s]);
            let moved_loop: Vec<DVec3> = (data.base_loop.iter())
                .map(|&v| base.positions[v as usize])
                .collect();
            let fill = with_rim(&data.fill, &moved_loop, &data.base_loop);
            let volume_rebuilt_fill_ml = fill_hole(&base, &data.base_loop, &params)
                .ok()
                .map(|rebuilt| closed_volume(&patch, &rebuilt.mesh).0);
            let mut breast = closed_soup(&patch, &fill);
            // the chest skin over the implant beyond the native breast (none where the
            // implant lies on the fill-in's bed, whose feet all lie inside the curve)
            if let Some(implant) = &self.implants[s] {
                let over = triangles_over_implant(
                    &self.base,
                    &self.beds[s],
                    &implant.anchor,
                    &implant.thickness,
                    &implant.fold,
                );
                let triangles: Vec<[u32; 3]> =
                    over.iter().map(|&t| self.base.triangles[t]).collect();
                let swept = swept_prisms(&self.base.positions, &base.positions, &triangles);
                breast = joined(&breast, &swept);
            }
            let (volume_ml, centre_mm) = soup_volume(&breast);
            let quadrant_volume_ml = quadrant_volumes_ml(
                &breast,
                &QuadrantLines::of_breast(side, &landmarks),
                self.frame.sternal().anterior(),
            )
            .ok();
            let moved_fill = moved(&data.fill, &maps.fills[s]);
            let (volume_moved_fill_ml, _) = closed_volume(&patch, &moved_fill);
            out.push(BreastVolume {
                volume_before_ml: data.volume_before_ml,
                volume_ml,
                volume_rebuilt_fill_ml,
                volume_moved_fill_ml,
                centre_before_mm: data.centre_before_mm,
                centre_mm,
                quadrant_volume_ml,
            });
        }
        [out[0], out[1]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fill_with_a_rim_closes_a_box_of_known_volume() {
        // The bottom of a 20 x 10 mm box (the fill, its loop's four corners first, facing
        // +z like the skin) and its top 7 mm higher (the patch, facing +z): joined by the
        // strip, the closed volume is the box's, 1.4 ml, whichever way the fill runs.
        let corners = [
            DVec3::ZERO,
            DVec3::new(20.0, 0.0, 0.0),
            DVec3::new(20.0, 10.0, 0.0),
            DVec3::new(0.0, 10.0, 0.0),
        ];
        let lift = DVec3::new(0.0, 0.0, 7.0);
        let top = corners.map(|p| p + lift);
        let patch = TriMesh::new(top.to_vec(), vec![[0, 1, 2], [0, 2, 3]]);
        let fill = TriMesh::new(corners.to_vec(), vec![[0, 1, 2], [0, 2, 3]]);
        let keys = [0, 1, 2, 3];
        let (volume_ml, centre) = closed_volume(&patch, &with_rim(&fill, &top, &keys));
        assert!((volume_ml - 1.4).abs() < 1e-12, "{volume_ml}");
        assert!(
            centre.distance(DVec3::new(10.0, 5.0, 3.5)) < 1e-9,
            "{centre}"
        );
        // The loop numbered the other way round (the fill runs 1 -> 0 along it).
        let reversed = [corners[0], corners[3], corners[2], corners[1]];
        let fill = TriMesh::new(reversed.to_vec(), vec![[0, 2, 1], [0, 3, 2]]);
        let rim = reversed.map(|p| p + lift);
        let (volume_ml, _) = closed_volume(&patch, &with_rim(&fill, &rim, &keys));
        assert!((volume_ml - 1.4).abs() < 1e-12, "{volume_ml}");
    }

    /// A circle of radius 70 mm drawn as 1,000 chords (unevenly spaced, as a cut curve's
    /// points are): the points come out on the circle, as many as the length asks, and
    /// evenly spaced in arc length (chord 2R sin(π/n)), to the polyline's own deviation
    /// from the circle (R (1 - cos(π/1000)) ≈ 3.5e-4 mm): bound 1e-3 mm.
    #[test]
    fn points_along_a_loop_are_evenly_spaced_by_arc_length() {
        let radius_mm = 70.0;
        let loop_points: Vec<DVec3> = (0..1000)
            .map(|k| {
                let t = k as f64 / 1000.0;
                // a non-uniform parameter along the circle
                let angle = std::f64::consts::TAU * (t + 0.05 * (std::f64::consts::TAU * t).sin());
                DVec3::new(radius_mm * angle.cos(), radius_mm * angle.sin(), 5.0)
            })
            .collect();
        let points = points_along_loop(&loop_points, 10.0);
        let circumference = std::f64::consts::TAU * radius_mm;
        assert_eq!(points.len(), (circumference / 10.0).round() as usize);
        assert_eq!(points[0], loop_points[0]);
        let n = points.len();
        let chord = 2.0 * radius_mm * (std::f64::consts::PI / n as f64).sin();
        for k in 0..n {
            let p = points[k];
            assert!((p.truncate().length() - radius_mm).abs() < 1e-3, "{p}");
            let gap = p.distance(points[(k + 1) % n]);
            assert!((gap - chord).abs() < 1e-3, "{k}: {gap} against {chord}");
        }
        assert_eq!(points_along_loop(&loop_points[..3], 100.0).len(), 3);
    }
}
