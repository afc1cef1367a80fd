//! Placing an implant: the bed it lies on (the fill-in's or the pocket's), the anchor
//! and its fit, the planned fold, and the template.

use super::*;

/// What [`Simulation::fit_on`] found: bed, feet, pocket bounds (at the final fold
/// lowering), requested and fitted anchor, fold lowering (mm).
type FittedOn = (
    ImplantBed,
    BedFeet,
    Option<PocketBounds>,
    Anchor,
    Anchor,
    f64,
);

/// An implant that does not fit its pocket because it reaches past one of the pocket's
/// anatomical limits gets the error naming that limit; other errors pass.
fn pocket_limit_error(
    side: Side,
    bounds: Option<&PocketBounds>,
    error: SimulationError,
) -> SimulationError {
    let (SimulationError::ImplantLargerThanFootprint { near_mm, .. }, Some(bounds)) =
        (&error, bounds)
    else {
        return error;
    };
    match bounds.violation(DVec3::from_array(*near_mm)) {
        Some((limit, beyond_mm)) => SimulationError::PocketLimit {
            side,
            limit,
            beyond_mm,
        },
        None => error,
    }
}

/// A move may take the implant this much further past a pocket's limit than its
/// default position lies before it is refused (mm): the pushes of the fit undo that much.
const MOVE_PAST_LIMIT_TOLERANCE_MM: f64 = 2.0;

/// The footprint's lowest point may lie this far below a fold lowered by a given amount
/// (mm): the footprint's own tolerance on the bed's edge.
const FLOOR_TOLERANCE_MM: f64 = FOOTPRINT_TOLERANCE_MM;

/// Outline points of the footprint checked against the planned fold.
const FLOOR_CHECK_POINTS: usize = 72;

/// The height (standing frame, mm) of the lowest point of the footprint of `shape`
/// anchored at `anchor` on `bed`.
fn lowest_footprint_y_mm(
    bed: &ImplantBed,
    anchor: &Anchor,
    shape: &ImplantShape,
    frame: &AnatomicalFrame,
) -> f64 {
    (shape.footprint_outline_mm(FLOOR_CHECK_POINTS).into_iter())
        .filter_map(|local| bed.at(anchor.uv_of(local)))
        .map(|at| frame.to_local(at.position).y)
        .fold(f64::INFINITY, f64::min)
}

impl Simulation {
    /// The default anchor of one side (bed parameters `(u, v)`, mm).
    pub fn default_anchor_uv(&self, side: Side) -> DVec2 {
        self.sides[side as usize].default_uv
    }

    /// The fold lowering (mm) the pocket of `side` is planned with for an implant of
    /// `shape` by the side's rule (0 without pockets).
    pub fn fold_lowering_mm(&self, side: Side, shape: &ImplantShape) -> f64 {
        self.fold_rule(side, &Placement::default())
            .map_or(0.0, |rule| {
                rule.mm(shape, nipple_to_fold_mm(side, &self.landmarks))
            })
    }

    /// The fold lowering rule for an implant placed with `placement`: its own lowering
    /// if it gives one, else the side's; `None` without pockets.
    pub(super) fn fold_rule(&self, side: Side, placement: &Placement) -> Option<FoldLowering> {
        let side_rule = self.options.pocket?[side as usize].fold_lowering;
        Some(
            placement
                .fold_lowering_mm
                .map_or(side_rule, FoldLowering::Mm),
        )
    }

    /// Checks an implant's own fold lowering: finite, and from 0 to the depth the side's
    /// pocket was built for.
    pub(super) fn check_fold_lowering(
        &self,
        side: Side,
        placement: &Placement,
    ) -> Result<(), SimulationError> {
        let Some(mm) = placement.fold_lowering_mm else {
            return Ok(());
        };
        let deepest_mm = self.options.pocket.map_or(0.0, |limits| {
            limits[side as usize].fold_lowering.deepest_mm()
        });
        if mm.is_finite() && (0.0..=deepest_mm).contains(&mm) {
            return Ok(());
        }
        Err(SimulationError::BadPlacement {
            side,
            what: "fold lowering (mm)",
            value: mm,
            expected: format!(
                "from 0 to {deepest_mm:.0} mm, as deep as the side's pocket was built"
            ),
        })
    }

    /// Places (or replaces) the implant of one side and rebuilds its template; the
    /// session drops back to stage 1 and keeps its displacement as the warm start. On
    /// error nothing changes.
    ///
    /// Errors: a move or rotation that is not finite, a bed moved further forward than
    /// [`MAX_FORWARD_SHIFT_MM`] or closer than [`MIN_WALL_CLEARANCE_MM`] to the posterior
    /// wall, an anchor walked off the bed, an implant whose footprint does not fit on
    /// the bed, a template without implant vertices.
    pub fn set_implant(
        &mut self,
        side: Side,
        shape: ImplantShape,
        placement: Placement,
    ) -> Result<&PlacedImplant, SimulationError> {
        let start = Instant::now();
        let s = side as usize;
        let shift = self.options.shift_mm - placement.move_mm.z;
        let max_shift = self.rear_wall_offset_mm - MIN_WALL_CLEARANCE_MM;
        if !(shift.is_finite() && shift >= -MAX_FORWARD_SHIFT_MM && shift <= max_shift) {
            return Err(SimulationError::BadPlacement {
                side,
                what: "move z (mm)",
                value: placement.move_mm.z,
                expected: format!(
                    "the bed lies {:.1} mm behind the fill-in by default; it may move from \
                     {MAX_FORWARD_SHIFT_MM} mm in front of the fill-in to {MIN_WALL_CLEARANCE_MM} mm \
                     before the posterior wall, so z in {:.1}..={:.1}",
                    self.options.shift_mm,
                    self.options.shift_mm - max_shift,
                    self.options.shift_mm + MAX_FORWARD_SHIFT_MM
                ),
            });
        }
        // the fill-in's bed first, then the pocket's (or the other way round where the
        // fold is lowered): the first on which the implant fits
        self.check_fold_lowering(side, &placement)?;
        let fold_lowering_mm = self.fold_rule(side, &placement).map_or(0.0, |rule| {
            rule.mm(&shape, nipple_to_fold_mm(side, &self.landmarks))
        });
        let mut order: Vec<usize> = (0..self.bed_choices[s].len()).collect();
        if fold_lowering_mm > 0.0 {
            order.sort_by_key(|&k| self.bed_choices[s][k].bounds.is_none());
        }
        // a move the user asked for past a pocket's limit ends the search; where no bed
        // takes the implant, a pocket's limit it reached is the clearest error
        let moved = placement.move_mm.truncate() != DVec2::ZERO;
        let mut outcome = Err(SimulationError::BadModel("no bed".into()));
        let mut limit_reached = None;
        let mut chosen = 0;
        for k in order {
            let choice = &self.bed_choices[s][k];
            outcome = self.fit_on(side, choice, shift, &shape, &placement, fold_lowering_mm);
            chosen = k;
            match &outcome {
                Ok(_) => break,
                Err(limit @ SimulationError::PocketLimit { .. }) => {
                    if moved {
                        break;
                    }
                    limit_reached.get_or_insert_with(|| limit.clone());
                }
                Err(_) => {}
            }
        }
        if let (Err(_), Some(limit)) = (&outcome, limit_reached) {
            outcome = Err(limit);
        }
        let (bed, feet, bounds, requested, anchor, fold_lowering_mm) = outcome?;
        let radius = self.options.rim_smoothing_on_mesh(self.spacing_mm);
        let layer_mm = self.options.template_layer_on_mesh(self.spacing_mm);
        let thickness = SmoothedThickness::new(shape, radius);
        let fold = self.planned_fold(side, fold_lowering_mm);
        let template = build_template(
            &self.finest,
            &self.bed_choices[s][chosen].candidates,
            &feet,
            &anchor,
            &thickness,
            &TemplateRules {
                hold_bed: self.options.hold_bed,
                layer_mm,
                on_wall: &self.on_wall,
                slides: self.options.skin_slides.then_some(&self.on_skin[..]),
                fold,
            },
        )?;
        let fold_vertices = self.fold_line(&fold, &template);
        self.beds[s] = bed;
        self.feet[s] = feet;
        self.pocket_bounds[s] = bounds;
        self.constraints_changed();
        Ok(self.implants[s].insert(PlacedImplant {
            shape,
            placement,
            anchor,
            fit_shift_mm: requested.local(anchor.uv),
            fold_lowering_mm,
            template,
            thickness,
            fold,
            fold_vertices,
            setup_ms: elapsed_ms(start),
        }))
    }

    /// The planned fold of `side`, `fold_lowering_mm` below the native one's lowest point.
    fn planned_fold(&self, side: Side, fold_lowering_mm: f64) -> FoldPlane {
        let fold_y_mm = planned_fold_y_mm(side, &self.frame, &self.landmarks, fold_lowering_mm);
        FoldPlane {
            point: self.frame.to_file(DVec3::new(0.0, fold_y_mm, 0.0)),
            up: self.frame.up(),
            taper_mm: FOLD_TAPER.on_mesh(self.spacing_mm),
        }
    }

    /// The skin vertices along the planned `fold` ([`PlacedImplant::fold_vertices`]): on
    /// the skin, up to one finest spacing below the fold's height (standing frame),
    /// across the width of the template's vertices below the implant's middle, and
    /// neither template vertices nor their neighbours (a held vertex next to one pushed
    /// by the implant folds the element between them over).
    pub(super) fn fold_line(&self, fold: &FoldPlane, template: &ImplantTemplate) -> Vec<u32> {
        let local = |v: u32| self.frame.to_local(self.finest.positions[v as usize]);
        let pushed: Vec<DVec3> = template.pushed_vertices().map(|&(v, _)| local(v)).collect();
        let Some(middle_y_mm) = pushed
            .iter()
            .map(|p| p.y)
            .reduce(f64::max)
            .zip(pushed.iter().map(|p| p.y).reduce(f64::min))
            .map(|(top, bottom)| 0.5 * (top + bottom))
        else {
            return Vec::new();
        };
        let (x_lo, x_hi) = pushed
            .iter()
            .filter(|p| p.y < middle_y_mm)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p.x), hi.max(p.x))
            });
        let mut in_template = vec![false; self.finest.positions.len()];
        for &(v, _) in template.pushed_vertices() {
            in_template[v as usize] = true;
        }
        let pushed_near = |v: u32| {
            let v = v as usize;
            in_template[v]
                || self.neighbours[self.neighbour_ptr[v]..self.neighbour_ptr[v + 1]]
                    .iter()
                    .any(|&w| in_template[w as usize])
        };
        (0..self.finest.positions.len() as u32)
            .filter(|&v| self.on_skin[v as usize])
            .filter(|&v| {
                let height_mm = fold.height_mm(self.finest.positions[v as usize]);
                let x = local(v).x;
                height_mm <= 0.0 && height_mm > -self.spacing_mm && x >= x_lo && x <= x_hi
            })
            .filter(|&v| !pushed_near(v))
            .collect()
    }

    /// The implant placed on `choice`'s bed shifted `shift` mm back: the bed and feet
    /// used, the pocket's bounds, the requested and the fitted anchor.
    ///
    /// Errors: as [`Simulation::set_implant`]; a move the user asked for that takes the
    /// implant past an anatomical limit of the pocket is [`SimulationError::PocketLimit`]
    /// (not undone by the fit).
    pub(super) fn fit_on(
        &self,
        side: Side,
        choice: &BedChoice,
        shift: f64,
        shape: &ImplantShape,
        placement: &Placement,
        fold_lowering_mm: f64,
    ) -> Result<FittedOn, SimulationError> {
        let (bed, feet) = if choice.bed.shift_mm == shift {
            (choice.bed.clone(), choice.feet.clone())
        } else {
            let bed = choice.bed.shifted(shift)?;
            let feet = choice.candidates.feet(&bed);
            (bed, feet)
        };
        // the pocket at the planned lowering (it was built for the deepest fold), for the
        // default anchor, the limit errors and how far the fit leaves the fold
        let limits = choice
            .bounds
            .and(self.options.pocket)
            .map(|l| l[side as usize]);
        let bounds_lowered = |lowering_mm| {
            limits.map(|l| PocketBounds::new(side, &self.frame, &self.landmarks, &l, lowering_mm))
        };
        let bounds = bounds_lowered(fold_lowering_mm);
        let limit_error = |error| pocket_limit_error(side, bounds.as_ref(), error);
        let default_uv = self.default_uv_on(side, &bed, shape, bounds.as_ref())?;
        let requested = resolve_anchor(&bed, &self.frame, default_uv, placement)?;
        // a move that takes the implant further past a limit than its default position
        // lies (the fit would undo it) is refused, naming the limit
        let beyond_limit_mm =
            |anchor: &Anchor| match check_footprint(&bed, anchor, shape, &self.frame)
                .map_err(limit_error)
            {
                Err(limit @ SimulationError::PocketLimit { beyond_mm, .. }) => {
                    Some((beyond_mm, limit))
                }
                _ => None,
            };
        let moved = placement.move_mm.truncate() != glam::DVec2::ZERO;
        if moved && let Some((beyond_mm, limit)) = beyond_limit_mm(&requested) {
            let unmoved = Placement {
                move_mm: DVec3::new(0.0, 0.0, placement.move_mm.z),
                ..*placement
            };
            let default_beyond_mm = resolve_anchor(&bed, &self.frame, default_uv, &unmoved)
                .ok()
                .and_then(|anchor| beyond_limit_mm(&anchor))
                .map_or(0.0, |(mm, _)| mm);
            if beyond_mm > default_beyond_mm + MOVE_PAST_LIMIT_TOLERANCE_MM {
                return Err(limit);
            }
        }
        let anchor = if self.options.fit_footprint {
            fit_footprint(&bed, &self.frame, requested, placement.rotation_deg, shape)
        } else {
            check_footprint(&bed, &requested, shape, &self.frame).map(|()| requested)
        }
        .map_err(limit_error)?;
        // a lowering planned for the implant follows it where the fit moved it (the new
        // fold lies at its lower edge), no deeper than the pocket was built; a given one
        // holds
        let below_mm = bounds.map_or(0.0, |b| {
            b.floor_y_mm - lowest_footprint_y_mm(&bed, &anchor, shape, &self.frame)
        });
        let deepest_mm = limits.map_or(0.0, |l| l.fold_lowering.deepest_mm());
        let fold_lowering_mm = match self.fold_rule(side, placement) {
            Some(FoldLowering::ForImplant) if bounds.is_some() => {
                (fold_lowering_mm + below_mm).clamp(0.0, deepest_mm)
            }
            Some(FoldLowering::Mm(_)) if below_mm > FLOOR_TOLERANCE_MM => {
                return Err(SimulationError::PocketLimit {
                    side,
                    limit: "the planned fold",
                    beyond_mm: below_mm,
                });
            }
            _ if bounds.is_some() => fold_lowering_mm,
            _ => 0.0,
        };
        // the bounds the pocket ends with: at the fold the implant got
        let bounds = bounds_lowered(fold_lowering_mm);
        Ok((bed, feet, bounds, requested, anchor, fold_lowering_mm))
    }

    /// The default anchor of `side` for an implant of `shape` on `bed` (bed parameters):
    /// the rule's, on a pocket with a lowered fold taken down with it (see
    /// [`AnchorRule`]).
    pub(super) fn default_uv_on(
        &self,
        side: Side,
        bed: &ImplantBed,
        shape: &ImplantShape,
        bounds: Option<&PocketBounds>,
    ) -> Result<DVec2, SimulationError> {
        let start = self.sides[side as usize].default_uv;
        let floor_y_mm = bounds.map_or_else(
            || native_fold_y_mm(side, &self.frame, &self.landmarks),
            |b| b.floor_y_mm,
        );
        let lowering_mm = native_fold_y_mm(side, &self.frame, &self.landmarks) - floor_y_mm;
        match self.options.anchor_rule {
            AnchorRule::OnFold => {
                let half_height_mm = shape.footprint().height_mm() / 2.0;
                // straight down from behind the nipple (on the chest's radius through it)
                let behind = resolve_anchor(bed, &self.frame, start, &Placement::default())?;
                let across_mm = self.frame.to_local(behind.position).x;
                anchor_on_floor(
                    bed,
                    &self.frame,
                    start,
                    across_mm,
                    half_height_mm,
                    floor_y_mm,
                )
            }
            _ if lowering_mm > 0.0 => {
                let down = Placement::moved(0.0, -lowering_mm, 0.0);
                Ok(resolve_anchor(bed, &self.frame, start, &down)?.uv)
            }
            _ => Ok(start),
        }
    }
}
