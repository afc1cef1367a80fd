//! The loop seen from the frame, and the heights its Hermite splines give the lattice
//! points along each lattice row and column.

use super::base::gaussian_along_loop;
use super::frame::Frame;
use super::lattice::Lattice;
use glam::{DVec2, DVec3};

/// Largest spline end slope (mm of height per mm along the plane), about 80°: where the
/// base is steeper than this relative to the fitted plane, its tangent says little about
/// the hole, and a tangent pointing backwards would fold the curve.
const MAX_SLOPE: f64 = 5.7;

/// Bisection steps locating a lattice coordinate on a Hermite curve: 2^-40 of the
/// parameter range, far below a micrometre on any hole.
const HERMITE_BISECTION_STEPS: usize = 40;

/// The loop seen from the fitted plane.
pub(super) struct Boundary {
    /// In-plane coordinates `(u, v)` of the loop vertices (mm).
    pub(super) points: Vec<DVec2>,
    /// Height of each loop vertex above the plane (mm).
    pub(super) heights: Vec<f64>,
    /// Smoothed base normal at each loop vertex in frame coordinates, on the side of the
    /// plane normal (the tangent plane is the same either way).
    normals: Vec<DVec3>,
}

/// Where a lattice line meets the boundary.
struct Crossing {
    /// Coordinate along the line (mm).
    along: f64,
    /// The boundary edge crossed, `edge -> edge + 1`.
    edge: usize,
    /// Fraction of the way along that edge.
    t: f64,
}

/// One end of a lattice line's Hermite spline.
struct SplineEnd {
    /// Coordinate along the line (mm).
    along: f64,
    /// Height above the plane (mm).
    height: f64,
    /// The base's slope along the line (mm of height per mm).
    slope: f64,
}

/// A family of lattice lines: rows run along `u`, columns along `v`.
#[derive(Debug, Clone, Copy)]
pub(super) enum Axis {
    U,
    V,
}

impl Axis {
    /// The coordinate that varies along a line.
    fn along(self) -> usize {
        match self {
            Axis::U => 0,
            Axis::V => 1,
        }
    }

    /// The coordinate that is constant along a line.
    fn across(self) -> usize {
        1 - self.along()
    }
}

impl Boundary {
    /// The loop in the fitted plane's frame, with the base normals Gaussian-filtered.
    pub(super) fn project(
        frame: &Frame,
        loop_positions: &[DVec3],
        base_normals: &[DVec3],
        sigma_mm: f64,
    ) -> Boundary {
        let local: Vec<DVec3> = loop_positions.iter().map(|&p| frame.to_local(p)).collect();
        let local_normals: Vec<DVec3> = base_normals
            .iter()
            .zip(loop_positions)
            .map(|(&n, &p)| {
                let n = frame.normal_to_local(p, n);
                if n.z < 0.0 { -n } else { n }
            })
            .collect();
        Boundary {
            points: local.iter().map(|p| p.truncate()).collect(),
            heights: local.iter().map(|p| p.z).collect(),
            normals: gaussian_along_loop(&local_normals, loop_positions, sigma_mm),
        }
    }

    /// Where the line `across = level` of `axis` crosses the boundary, sorted along it.
    /// Half-open edges make the count even, so consecutive pairs bound inside segments.
    fn crossings(&self, axis: Axis, level: f64) -> Vec<Crossing> {
        let (along, across) = (axis.along(), axis.across());
        let n = self.points.len();
        let mut crossings: Vec<Crossing> = (0..n)
            .filter_map(|edge| {
                let (a, b) = (self.points[edge], self.points[(edge + 1) % n]);
                if (a[across] <= level) == (b[across] <= level) {
                    return None;
                }
                let t = (level - a[across]) / (b[across] - a[across]);
                Some(Crossing {
                    along: a[along] + t * (b[along] - a[along]),
                    edge,
                    t,
                })
            })
            .collect();
        crossings.sort_by(|x, y| x.along.total_cmp(&y.along));
        crossings
    }

    /// Height and base slope where a line of `axis` crosses the boundary.
    fn spline_end(&self, crossing: &Crossing, axis: Axis) -> SplineEnd {
        let (from, to) = (crossing.edge, (crossing.edge + 1) % self.points.len());
        let t = crossing.t;
        let height = self.heights[from] + t * (self.heights[to] - self.heights[from]);
        let normal = self.normals[from].lerp(self.normals[to], t);
        // The tangent plane n . (du, dv, dw) = 0 meets the line's vertical plane in
        // dw / d(along) = -n_along / n_w.
        let slope = -normal[axis.along()] / normal.z;
        SplineEnd {
            along: crossing.along,
            height,
            slope: if slope.is_nan() {
                0.0
            } else {
                slope.clamp(-MAX_SLOPE, MAX_SLOPE)
            },
        }
    }

    /// Per lattice point, the height of the Hermite spline of its line of `axis` and the
    /// spline's weight in the blend, or `None` outside the polygon.
    fn line_heights(&self, lattice: &Lattice, axis: Axis) -> Vec<Option<LineHeight>> {
        let mut heights = vec![None; lattice.len()];
        for line in 0..lattice.size[axis.across()] {
            let level = lattice.coordinate(axis.across(), line);
            for pair in self.crossings(axis, level).chunks_exact(2) {
                let entry = self.spline_end(&pair[0], axis);
                let exit = self.spline_end(&pair[1], axis);
                for k in lattice.indices_between(axis.along(), entry.along, exit.along) {
                    let along = lattice.coordinate(axis.along(), k);
                    let reach_mm = (along - entry.along) * (exit.along - along);
                    heights[lattice.index(axis, line, k)] = Some(LineHeight {
                        height: hermite(&entry, &exit, along),
                        weight: 1.0 / reach_mm.max(f64::MIN_POSITIVE),
                    });
                }
            }
        }
        heights
    }

    /// The lattice points inside the polygon and clear of its boundary, with their
    /// heights: the blend of their row and column splines.
    pub(super) fn interior_points(&self, lattice: &Lattice) -> (Vec<DVec2>, Vec<f64>) {
        let rows = self.line_heights(lattice, Axis::U);
        let columns = self.line_heights(lattice, Axis::V);
        let near = lattice.near_polygon(&self.points);
        (0..lattice.len())
            .filter(|&i| !near[i])
            .filter_map(|i| {
                let row = rows[i]?;
                let height = columns[i].map_or(row.height, |column| {
                    (row.weight * row.height + column.weight * column.height)
                        / (row.weight + column.weight)
                });
                Some((lattice.point(i), height))
            })
            .unzip()
    }
}

/// A lattice point's height on one spline, and how much the spline counts there.
#[derive(Debug, Clone, Copy)]
struct LineHeight {
    /// Height above the plane (mm).
    height: f64,
    /// `1 / (d_entry · d_exit)` (mm⁻²), the distances along the line to its two ends.
    weight: f64,
}

/// The paper's cubic Hermite curve from `entry` to `exit`, in the line's vertical plane
/// `(along, height)`: its end tangents are the base's unit tangents scaled by the chord
/// length (and a factor that makes it follow a circular arc), so a steep base bends the
/// curve like an arc rather than shooting over (a slope-valued spline `height(along)`
/// would bulge by `chord · slope / 8`).
/// Returns the curve's height where its `along` coordinate equals `along`, found by
/// bisection: `along(s)` runs from the entry to the exit, monotone because both tangents
/// point forward (the slope cap) and are at most three chords long along the line.
fn hermite(entry: &SplineEnd, exit: &SplineEnd, along: f64) -> f64 {
    let chord_along = exit.along - entry.along;
    if chord_along <= 0.0 {
        return 0.5 * (entry.height + exit.height);
    }
    let chord_mm = DVec2::new(chord_along, exit.height - entry.height).length();
    let (start_direction, end_direction) = (
        DVec2::new(1.0, entry.slope).normalize(),
        DVec2::new(1.0, exit.slope).normalize(),
    );
    // A Hermite curve whose tangents are the chord times 1 / cos²(turn / 4) follows a
    // circular arc turning by `turn` closely (the cubic Bézier arc), where plain chord
    // scaling would run flat and lose volume on a curved chest.
    let turn = start_direction.angle_to(end_direction).abs();
    let arc_length_mm = chord_mm / (0.25 * turn).cos().powi(2);
    // `along(s)` is monotone while each tangent's `along` part stays within three times
    // the chord's (Fritsch-Carlson); a very steep row would otherwise double back.
    let monotone_length = |direction: DVec2| arc_length_mm.min(3.0 * chord_along / direction.x);
    let (start_tangent, end_tangent) = (
        start_direction * monotone_length(start_direction),
        end_direction * monotone_length(end_direction),
    );
    let (start, end) = (
        DVec2::new(entry.along, entry.height),
        DVec2::new(exit.along, exit.height),
    );
    let point = |s: f64| {
        let (s2, s3) = (s * s, s * s * s);
        (2.0 * s3 - 3.0 * s2 + 1.0) * start
            + (s3 - 2.0 * s2 + s) * start_tangent
            + (3.0 * s2 - 2.0 * s3) * end
            + (s3 - s2) * end_tangent
    };
    let (mut low, mut high) = (0.0, 1.0);
    for _ in 0..HERMITE_BISECTION_STEPS {
        let middle = 0.5 * (low + high);
        if point(middle).x < along {
            low = middle;
        } else {
            high = middle;
        }
    }
    point(0.5 * (low + high)).y
}
