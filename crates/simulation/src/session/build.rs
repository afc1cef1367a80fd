//! Preparing a session: the levels' tissue models, the cylinder, the fill-ins' and
//! pockets' beds with their default anchors, the template candidates, the held wall and
//! band, and the maps of the scan onto the finest level.

use super::*;

/// A bed's pocket: its bed and its limits, per side where a pocket can carry an implant.
type PocketBeds = [Option<(ImplantBed, PocketBounds)>; 2];

/// The vertices held at every stage and the finest level's boundary classes.
struct HeldVertices {
    wall: Vec<u32>,
    on_wall: Vec<bool>,
    on_band: Vec<bool>,
    on_skin: Vec<bool>,
    coarse_walls: Vec<Vec<u32>>,
}

/// The scan and the points carried on it, located in the finest level.
struct ScanMaps {
    scan_rest: Vec<DVec3>,
    scan_map: PointMap,
    scan_smoother: SurfaceSmoother,
    landmark_feet: ScanFeet,
    control_points: [Vec<DVec3>; 2],
    control_point_feet: [ScanFeet; 2],
}

impl Simulation {
    /// Prepares a session: the tissue model of every level, the implant beds at the
    /// default shift with their default anchors, the template index, the vertices held
    /// at every stage (wall, band, the strip over the sternum), and the maps of the scan
    /// and landmarks onto the finest level.
    ///
    /// Errors: bad options, a hierarchy without levels or with inverted elements, a
    /// fill-in that cannot carry an implant.
    pub fn new(
        input: PatientInput,
        options: SimulationOptions,
    ) -> Result<Simulation, SimulationError> {
        options.check()?;
        let frame = *input.frame;
        let (finest, spacing_mm, mut levels, muscle) = tissue_levels(&input, &options)?;
        let closed = input.closed_surface;
        // one cylinder about the body's axis through both fill-ins
        let fill_points: Vec<DVec3> = Side::BOTH
            .iter()
            .flat_map(|&s| input.breasts.breast(s).fill.mesh.positions.iter().copied())
            .collect();
        let cylinder = ChestCylinder::fit(&fill_points, &frame.sternal());
        let (sides, beds, pocket_beds) = sides_and_beds(&input, &options, &cylinder)?;
        let bed_choices = bed_choices(&finest, closed, &options, &beds, &pocket_beds);
        let finest_wall_and_band =
            wall_vertices(&finest, closed, spacing_mm * WALL_TOLERANCE_FACTOR)?;
        if let Some(skin) = options.skin {
            let mut not_skin = vec![false; finest.positions.len()];
            for &(v, _) in &finest_wall_and_band {
                not_skin[v as usize] = true;
            }
            levels[0].set_membranes(&skin.membranes(&finest, options.tissue, &not_skin))?;
        }
        let every_bed: Vec<&ImplantBed> = bed_choices.iter().flatten().map(|c| &c.bed).collect();
        let HeldVertices {
            wall,
            on_wall,
            on_band,
            on_skin,
            coarse_walls,
        } = held_vertices(
            &input,
            &options,
            &finest,
            (&beds, &every_bed),
            levels.len(),
            &finest_wall_and_band,
        )?;
        let ScanMaps {
            scan_rest,
            scan_map,
            scan_smoother,
            landmark_feet,
            control_points,
            control_point_feet,
        } = scan_maps(&input, &finest, spacing_mm, &options)?;
        let n = finest.positions.len();
        let (neighbour_ptr, neighbours) = vertex_neighbours(&finest);
        let never_moved = never_moved(n, &wall, &bed_choices);
        Ok(Simulation {
            never_moved,
            pocket_bounds: bed_choices.each_ref().map(|choices| choices[0].bounds),
            feet: bed_choices
                .each_ref()
                .map(|choices| choices[0].feet.clone()),
            beds: bed_choices.each_ref().map(|choices| choices[0].bed.clone()),
            bed_choices,
            coarse_walls,
            coarse_operator: options.multigrid.coarse_operator,
            coarse_fallbacks: 0,
            neighbour_ptr,
            neighbours,
            frame,
            levels,
            muscle,
            spacing_mm,
            rear_wall_offset_mm: closed.rear_wall_offset_mm,
            cylinder,
            sides,
            wall,
            on_wall,
            on_band,
            on_skin,
            implants: [None, None],
            stage: StageState::Implant,
            multigrid: None,
            multigrid_builds: 0,
            dirty: true,
            u: vec![DVec3::ZERO; n],
            f_ext: Vec::new(),
            last_relative_residual: 0.0,
            last_residual_mn: 0.0,
            stage_cycles: 0,
            fresh: true,
            released: false,
            stage_one_search: false,
            stage_one_residuals: Vec::new(),
            anderson: AndersonMixing::new(ANDERSON_DEPTH),
            newton_krylov: false,
            aimed_tolerance: options.relative_tolerance,
            gravity_guess: None,
            warmup_left: 0,
            last_energy: None,
            last_step: 1.0,
            scan_rest,
            scan_map,
            scan_smoother,
            scan_carry: None,
            landmarks: input.landmarks.clone(),
            landmark_feet,
            control_points,
            control_point_feet,
            base: input.breasts.base.mesh.clone(),
            mesh_maps: None,
            finest,
            options,
        })
    }
}

/// The finest mesh, its spacing (mm), the tissue model of every level used (the
/// pectoralis major's elements with its material where [`SimulationOptions::muscle`]
/// gives one) and the muscle layer on the finest level.
fn tissue_levels(
    input: &PatientInput,
    options: &SimulationOptions,
) -> Result<(TetMesh, f64, Vec<FemModel>, MuscleLayer), SimulationError> {
    let Some(level0) = input.tets.levels.first() else {
        return Err(SimulationError::BadModel(
            "the hierarchy has no level".into(),
        ));
    };
    let finest = level0.mesh.clone();
    let spacing_mm = level0.spacing_mm;
    let level_count = options.max_levels.unwrap_or(usize::MAX).max(1);
    let layer_of =
        |mesh: &TetMesh| MuscleLayer::new(mesh, input.closed_surface, input.frame, input.landmarks);
    let muscle = layer_of(&finest)?;
    let mut levels = Vec::with_capacity(level_count.min(input.tets.levels.len()));
    for (l, level) in input.tets.levels.iter().take(level_count).enumerate() {
        let mut model = FemModel::homogeneous(&level.mesh, options.tissue)?;
        if let Some(material) = options.muscle {
            let coarse;
            let layer = if l == 0 {
                &muscle
            } else {
                coarse = layer_of(&level.mesh)?;
                &coarse
            };
            for &e in layer.elements.iter().flatten() {
                model.set_material(e as usize, material)?;
            }
        }
        levels.push(model);
    }
    levels[0].set_inversion_barrier(options.inversion_barrier)?;
    levels[0].set_compression_penalty(options.compression_penalty)?;
    Ok((finest, spacing_mm, levels, muscle))
}

/// Each side's data with its default anchor, its fill-in's bed (over the chest's
/// cylinder, or its own where the fill-in folds over seen from that axis) and its
/// pocket's bed where the pocket can carry an implant.
fn sides_and_beds(
    input: &PatientInput,
    options: &SimulationOptions,
    cylinder: &ChestCylinder,
) -> Result<([SideData; 2], [ImplantBed; 2], PocketBeds), SimulationError> {
    let frame = *input.frame;
    let closed = input.closed_surface;
    let sides = Side::BOTH.map(|side| {
        let b = input.breasts.breast(side);
        let (volume_before_ml, centre_before_mm) = closed_volume(&b.patch.mesh, &b.fill.mesh);
        SideData {
            fill: b.fill.mesh.clone(),
            boundary_count: b.fill.boundary_to_base.len(),
            base_loop: b.fill.boundary_to_base.clone(),
            patch: b.patch.mesh.clone(),
            volume_before_ml,
            centre_before_mm,
            default_uv: DVec2::ZERO,
        }
    });
    // the chest-wide cylinder, or where the fill-in folds over seen from its axis
    // (a steep lateral fill-in), one fitted to that fill-in alone
    let bed_over = |side: Side, surface: &TriMesh, boundary_count: usize| {
        let data = &sides[side as usize];
        ImplantBed::new(side, surface, boundary_count, cylinder, options.shift_mm).or_else(
            |error| {
                let own = ChestCylinder::fit(&data.fill.positions, &frame.sternal());
                ImplantBed::new(side, surface, boundary_count, &own, options.shift_mm)
                    .map_err(|_| error)
            },
        )
    };
    let pockets = Side::BOTH.map(|side| {
        let limits = options.pocket?[side as usize];
        // as deep as any implant's planned fold; each implant's own bounds are
        // checked when it is placed
        let deepest = limits.fold_lowering.deepest_mm();
        let bounds = PocketBounds::new(side, &frame, input.landmarks, &limits, deepest);
        let surface = pocket_surface(
            &input.breasts.base.mesh,
            &input.breasts.breast(side).fill,
            &frame,
            &bounds,
            Some(&closed.clip_box),
            limits.margin_mm,
        )?;
        Some((bounds, surface))
    });
    // the fill-in's bed, and the pocket's where it can carry an implant (a graph
    // over the same cylinder once its folding chest triangles are dropped)
    let fill_bed_of = |side: Side| {
        let data = &sides[side as usize];
        bed_over(side, &data.fill, data.boundary_count)
    };
    let beds = [fill_bed_of(Side::Left)?, fill_bed_of(Side::Right)?];
    let pocket_beds = Side::BOTH.map(|side| {
        let (bounds, pocket) = pockets[side as usize].as_ref()?;
        let fill_bed = &beds[side as usize];
        let pocket = pocket
            .clone()
            .without_folds(&fill_bed.cylinder, options.shift_mm)?;
        let bed = ImplantBed::new(
            side,
            &pocket.mesh,
            pocket.boundary_count,
            &fill_bed.cylinder,
            options.shift_mm,
        )
        .ok()?;
        Some((bed, *bounds))
    });
    let mut sides = sides;
    for side in Side::BOTH {
        let bed = &beds[side as usize];
        let uv = match options.anchor_rule {
            AnchorRule::FootprintCentre => bed.centroid_uv(),
            // on-fold walks down from behind the nipple for each implant
            AnchorRule::BehindNipple | AnchorRule::OnFold => {
                let nipple = input.landmarks.get(nipple_of(side));
                let c = bed.cylinder.to_cylindrical(nipple);
                DVec2::new(c.x, c.y)
            }
        };
        if bed.at(uv).is_none() {
            return Err(SimulationError::BadFillIn {
                side,
                reason: format!(
                    "the default anchor ({}) does not lie on it",
                    options.anchor_rule
                ),
            });
        }
        sides[side as usize].default_uv = uv;
    }
    Ok((sides, beds, pocket_beds))
}

/// Each side's beds to try with their template candidates: the fill-in's, then the
/// pocket's where there is one.
fn bed_choices(
    finest: &TetMesh,
    closed: &ClosedSurface,
    options: &SimulationOptions,
    beds: &[ImplantBed; 2],
    pocket_beds: &PocketBeds,
) -> [Vec<BedChoice>; 2] {
    let max_edge = finest
        .tets
        .iter()
        .flat_map(|t| {
            [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)].map(|(a, b)| {
                finest.positions[t[a] as usize].distance(finest.positions[t[b] as usize])
            })
        })
        .fold(0.0, f64::max);
    let (back_mm, front_mm) = (
        closed.rear_wall_offset_mm + 2.0 * max_edge,
        MAX_FORWARD_SHIFT_MM + options.shift_mm.max(0.0) + 2.0 * max_edge,
    );
    // candidates over the fill-in's bed (the paper's), and over each pocket
    let [fill_left, fill_right] =
        TemplateIndex::new(finest, [&beds[0], &beds[1]], back_mm, front_mm).sides;

    let pocket_candidates = pocket_beds.each_ref().map(|pocket| {
        let (bed, _) = pocket.as_ref()?;
        let [left, right] = TemplateIndex::new(finest, [bed, bed], back_mm, front_mm).sides;
        Some(match bed.side {
            Side::Left => left,
            Side::Right => right,
        })
    });
    let [pocket_left, pocket_right] = pocket_candidates;
    let sides_candidates = [
        (Side::Left, fill_left, pocket_left),
        (Side::Right, fill_right, pocket_right),
    ];
    sides_candidates.map(|(side, candidates, pocket_candidates)| {
        let s = side as usize;
        let fill = BedChoice {
            feet: candidates.feet(&beds[s]),
            candidates,
            bed: beds[s].clone(),
            bounds: None,
        };
        let pocket =
            (pocket_beds[s].as_ref())
                .zip(pocket_candidates)
                .map(|((bed, bounds), candidates)| BedChoice {
                    feet: candidates.feet(bed),
                    candidates,
                    bed: bed.clone(),
                    bounds: Some(*bounds),
                });
        match pocket {
            Some(pocket) => vec![fill, pocket],
            None => vec![fill],
        }
    })
}

/// The vertices held at every stage, on every level used: the wall, the band (except
/// where a clip plane cuts breast tissue in front of one of the default `beds`) and,
/// with [`SimulationOptions::hold_sternum`], the strip over the sternum (except in front
/// of any of `every_bed`, the fill-ins' and the pockets'); and the finest level's wall,
/// band and skin vertices.
fn held_vertices(
    input: &PatientInput,
    options: &SimulationOptions,
    finest: &TetMesh,
    (beds, every_bed): (&[ImplantBed; 2], &[&ImplantBed]),
    level_count: usize,
    finest_wall_and_band: &[(u32, bool)],
) -> Result<HeldVertices, SimulationError> {
    let closed = input.closed_surface;
    let sternum = options
        .hold_sternum
        .then(|| SternumStrip::new(input.frame, input.landmarks));
    let held = |mesh: &TetMesh, wall_and_band: &[(u32, bool)]| -> Vec<u32> {
        let in_front_of = |bed: &ImplantBed, p: DVec3| {
            let c = bed.cylinder.to_cylindrical(p);
            bed.at(DVec2::new(c.x, c.y)).is_some_and(|b| c.z > b.w)
        };
        let mut held = vec![false; mesh.positions.len()];
        for &(v, band) in wall_and_band {
            let p = mesh.positions[v as usize];
            held[v as usize] = !band || !beds.iter().any(|bed| in_front_of(bed, p));
        }
        if let Some(strip) = &sternum {
            for (v, &p) in mesh.positions.iter().enumerate() {
                held[v] |= strip.contains(p) && !every_bed.iter().any(|bed| in_front_of(bed, p));
            }
        }
        (0..mesh.positions.len() as u32)
            .filter(|&v| held[v as usize])
            .collect()
    };
    let wall = held(finest, finest_wall_and_band);
    let mut on_band = vec![false; finest.positions.len()];
    let mut on_skin = vec![false; finest.positions.len()];
    for &v in &finest.boundary().tet_vertex {
        on_skin[v as usize] = true;
    }
    for &(v, band) in finest_wall_and_band {
        on_band[v as usize] = band;
        on_skin[v as usize] = false;
    }
    let mut on_wall = vec![false; finest.positions.len()];
    for &v in &wall {
        on_wall[v as usize] = true;
    }
    let coarse_walls = input.tets.levels[1..level_count]
        .iter()
        .map(|l| {
            let wall_and_band =
                wall_vertices(&l.mesh, closed, l.spacing_mm * WALL_TOLERANCE_FACTOR)?;
            Ok(held(&l.mesh, &wall_and_band))
        })
        .collect::<Result<Vec<_>, SimulationError>>()?;
    Ok(HeldVertices {
        wall,
        on_wall,
        on_band,
        on_skin,
        coarse_walls,
    })
}

/// The finest vertices whose displacement is zero whatever the implants: on the wall
/// and a template candidate of no bed (a template may displace a wall vertex, which then
/// keeps its place through the gravity stage).
fn never_moved(vertex_count: usize, wall: &[u32], bed_choices: &[Vec<BedChoice>; 2]) -> Vec<u32> {
    let mut candidate = vec![false; vertex_count];
    for choice in bed_choices.iter().flatten() {
        for &v in &choice.candidates.vertices {
            candidate[v as usize] = true;
        }
    }
    (wall.iter().copied())
        .filter(|&v| !candidate[v as usize])
        .collect()
}

/// The locator of points in the finest level `finest` of spacing `spacing_mm`, with the
/// session's blend beyond it ([`OUTSIDE_BLEND_RADIUS`]); `None` without tetrahedra.
pub(super) fn field_locator(finest: &TetMesh, spacing_mm: f64) -> Option<FieldLocator<'_>> {
    FieldLocator::new(finest, OUTSIDE_BLEND_RADIUS.on_mesh(spacing_mm))
}

/// The scan's vertices, landmarks and cut-curve points located in the finest level.
fn scan_maps(
    input: &PatientInput,
    finest: &TetMesh,
    spacing_mm: f64,
    options: &SimulationOptions,
) -> Result<ScanMaps, SimulationError> {
    let locator = field_locator(finest, spacing_mm)
        .ok_or_else(|| SimulationError::BadModel("the finest level has no tetrahedra".into()))?;
    let scan_rest = input.scan.positions.clone();
    let scan_map = PointMap::new(&locator, &scan_rest, options.falloff_mm);
    let scan_smoother = SurfaceSmoother::with_support(
        input.scan,
        options.scan_smoothing_on_mesh(spacing_mm),
        &scan_map.support(),
    );
    let scan_index = mesh::SurfaceIndex::new(input.scan)
        .ok_or_else(|| SimulationError::BadModel("the scan has no triangles".into()))?;
    let landmark_feet = ScanFeet::locate(
        input.scan,
        &scan_index,
        input.landmarks.iter().map(|(_, p)| p),
    );
    let control_points = Side::BOTH.map(|side| {
        let curve = &input.breasts.breast(side).curve;
        let positions: Vec<DVec3> = curve.points.iter().map(|p| p.position).collect();
        points_along_loop(&positions, CARRIED_CONTROL_POINT_SPACING_MM)
    });
    let control_point_feet = control_points
        .each_ref()
        .map(|points| ScanFeet::locate(input.scan, &scan_index, points.iter().copied()));
    Ok(ScanMaps {
        scan_rest,
        scan_map,
        scan_smoother,
        landmark_feet,
        control_points,
        control_point_feet,
    })
}

/// The tissue over the sternum: within [`STERNUM_HALF_WIDTH_MM`] of the standing frame's
/// midline (`x = 0`, through Pj, vertical), the one the pockets keep their clearance
/// from, and between the heights of Pj and Px (none if Px is not below Pj), at any
/// depth. Why not along the line through Pj and Px: docs/dev/model-on-every-body.md,
/// session 39.
struct SternumStrip {
    frame: AnatomicalFrame,
    /// Px's height below Pj (mm, standing frame).
    px_below_pj_mm: f64,
}

impl SternumStrip {
    fn new(frame: &AnatomicalFrame, landmarks: &Landmarks) -> SternumStrip {
        SternumStrip {
            frame: *frame,
            px_below_pj_mm: -frame.to_local(landmarks.get(LandmarkName::Px)).y,
        }
    }

    fn contains(&self, p: DVec3) -> bool {
        let local = self.frame.to_local(p);
        local.x.abs() <= STERNUM_HALF_WIDTH_MM && (-self.px_below_pj_mm..=0.0).contains(&local.y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pocket::{PocketBounds, PocketLimits};
    use anatomy::Up;

    /// The strip held over the sternum lies inside both pockets' midline clearance, also
    /// with Px clicked 8 mm off the midline (a strip along the line through Pj and Px
    /// would reach 18 mm out at Px, 3 mm into a pocket): every point the strip holds, on a grid over the chest
    /// (2 mm steps), is one a pocket's bounds refuse as "the sternal midline region".
    #[test]
    fn the_sternum_strip_stays_inside_the_pockets_clearance() {
        let mut landmarks = phantom::generate(&phantom::PhantomParams::default()).landmarks;
        let frame = AnatomicalFrame::from_landmarks(&landmarks, Up::FILE_VERTICAL).unwrap();
        let px = landmarks.get(LandmarkName::Px);
        landmarks.set(LandmarkName::Px, px + frame.left() * 8.0);
        let frame = AnatomicalFrame::from_landmarks(&landmarks, Up::FILE_VERTICAL).unwrap();
        let strip = SternumStrip::new(&frame, &landmarks);
        let limits = PocketLimits::default();
        let bounds =
            Side::BOTH.map(|side| PocketBounds::new(side, &frame, &landmarks, &limits, 0.0));
        let mut held = 0;
        for i in -30..=30 {
            for j in -120..=10 {
                let local = DVec3::new(f64::from(i) * 2.0, f64::from(j) * 2.0, 30.0);
                let p = frame.to_file(local);
                if !strip.contains(p) {
                    continue;
                }
                held += 1;
                for b in &bounds {
                    let violation = b.violation(local).map(|(limit, _)| limit);
                    assert_eq!(violation, Some("the sternal midline region"), "{local}");
                }
            }
        }
        // Px's height bounds it below; 10 mm either side of the midline at 2 mm steps
        let px_below_pj_mm = -frame.to_local(landmarks.get(LandmarkName::Px)).y;
        let rows = (px_below_pj_mm / 2.0).floor() as usize + 1;
        assert_eq!(held, rows * 11, "Px {px_below_pj_mm:.1} mm below Pj");
    }
}
