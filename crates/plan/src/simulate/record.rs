//! What `result.json` records of a simulation (GUIDE section 5): the implants as
//! placed, the solver, the materials, the pockets and the fold.

use super::*;

/// The finite-element solve of a simulation.
#[derive(Debug, Clone, Serialize)]
pub struct SolverReport {
    /// V-cycles run (both stages).
    pub vcycles: usize,
    /// Relative residual before the last cycle of the last stage.
    pub relative_residual: f64,
    pub converged: bool,
    /// Wall-clock time of the solve (ms).
    pub time_ms: f64,
    /// Cycles of the implant stage and of the gravity correction.
    pub implant_stage_vcycles: usize,
    pub gravity_stage_vcycles: Option<usize>,
    /// Deformed finest elements with non-positive volume.
    pub inverted_elements: usize,
}

/// One side's implant as placed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImplantSummary {
    pub spec: String,
    /// The catalog entry's id and family, for a `catalog:ID` spec.
    pub catalog_id: Option<String>,
    pub family: Option<String>,
    pub shape: ImplantShape,
    /// Width (the diameter of a round implant), height and projection (mm).
    pub width_mm: f64,
    pub height_mm: f64,
    pub projection_mm: f64,
    pub volume_ml: f64,
    /// The volume the displacement template alone inserts into the finest mesh (ml: the
    /// growth of the elements crossing the bed with only the template's displacements
    /// applied): scaled to `covered_volume_ml`, less only where the unscaled template
    /// already inserts less.
    pub template_volume_ml: f64,
    /// The factor in (0, 1] the template's thicknesses were scaled by to insert
    /// `covered_volume_ml` (1: unscaled): how far the bed's curvature made the unscaled
    /// template overshoot.
    pub template_scale: f64,
    /// The implant's volume over the part of its footprint the finest mesh reaches (ml):
    /// less than `volume_ml` where the footprint lies beyond the model's side, where the
    /// scan ends; that part is left out of the prediction.
    pub covered_volume_ml: f64,
    /// The radius the template's thickness was mollified over at the implant's rim (mm;
    /// the default or the option, resolved on this model's mesh).
    pub rim_smoothing_mm: f64,
    /// The thickness of the tissue layer over the footprint that moves with the implant
    /// (mm; the default or the option, resolved on this model's mesh).
    pub template_layer_mm: f64,
    /// Skin vertices over a thin pocket that slide over the implant instead of being
    /// held (`--skin-slides`; 0 without).
    pub sliding_skin_vertices: usize,
    /// The move asked for (mm, anatomical frame).
    pub move_mm: [f64; 3],
    /// The turn asked for about the bed's normal (degrees, counter-clockwise from the
    /// front).
    pub rotation_deg: f64,
    /// The further move of the anchor along the bed that made the footprint fit (mm,
    /// implant's `x'` to the patient's left and `y'` up; zero when it fitted as asked).
    pub fit_shift_mm: [f64; 2],
    /// How far the fold is lowered for this implant (mm below the native fold's lowest
    /// point; 0 on the fill-in's bed).
    pub fold_lowering_mm: f64,
    /// Where the implant's anchor (the centre of its back) ended up on the bed (mm, the
    /// scan's frame).
    pub anchor_mm: [f64; 3],
}

impl ImplantSummary {
    /// What the prediction leaves out of the implant's volume, where more than 5% of it
    /// is left out: the part beyond the finest mesh ([`ImplantSummary::covered_volume_ml`]),
    /// and the part of the covered volume the template does not insert
    /// ([`ImplantSummary::template_volume_ml`]: it is only ever scaled down, so on a bed
    /// too flat to overshoot, the push cut at the planned fold is not made up).
    pub fn left_out(&self) -> Option<String> {
        let limit_ml = LEFT_OUT_WARNING_SHARE * self.volume_ml;
        let outside_ml = self.volume_ml - self.covered_volume_ml;
        let beyond = (outside_ml > limit_ml).then(|| {
            format!(
                "{outside_ml:.0} of its {:.0} ml lie beyond the model's side, where the scan \
                 ends: the prediction leaves that part out (a narrower implant, a more medial \
                 position, or a scan that reaches further round the side would include it)",
                self.volume_ml
            )
        });
        let short_ml = self.covered_volume_ml - self.template_volume_ml;
        let short = (short_ml > limit_ml).then(|| {
            format!(
                "its displacement template inserts only {:.0} of the {:.0} ml the model \
                 covers: the push ends at the planned fold, and the bed under the implant is \
                 too flat to make that up, so the prediction understates the breast's gain by \
                 about the difference",
                self.template_volume_ml, self.covered_volume_ml
            )
        });
        match (beyond, short) {
            (Some(a), Some(b)) => Some(format!("{a}; {b}")),
            (a, b) => a.or(b),
        }
    }

    /// The summary of an implant placed as `request` asked, `catalog_entry` the entry
    /// its spec names, if any.
    pub fn new(
        request: &ImplantRequest,
        placed: &PlacedImplant,
        catalog_entry: Option<&implant::CatalogEntry>,
    ) -> ImplantSummary {
        ImplantSummary {
            spec: request.spec.clone(),
            catalog_id: catalog_entry.map(|entry| entry.id().to_string()),
            family: catalog_entry.map(|entry| entry.family().to_string()),
            shape: placed.shape,
            width_mm: placed.shape.width_mm(),
            height_mm: placed.shape.height_mm(),
            projection_mm: placed.shape.projection_mm(),
            volume_ml: placed.shape.volume_ml(),
            template_volume_ml: placed.template.template_volume_ml,
            template_scale: placed.template.scale,
            covered_volume_ml: placed.template.covered_volume_ml,
            rim_smoothing_mm: placed.thickness.radius_mm(),
            template_layer_mm: placed.template.layer_mm,
            sliding_skin_vertices: placed.template.skin_vertices.len(),
            move_mm: request.move_mm.to_array(),
            rotation_deg: request.rotation_deg,
            fit_shift_mm: placed.fit_shift_mm.to_array(),
            fold_lowering_mm: placed.fold_lowering_mm,
            anchor_mm: placed.anchor.position.to_array(),
        }
    }
}

/// An isotropic elastic material of the simulation.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct MaterialReport {
    pub young_kpa: f64,
    pub poisson_ratio: f64,
    pub density_kg_m3: f64,
}

/// The skin layer of the simulation ([`simulation::skin`]).
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct SkinReport {
    pub young_kpa: f64,
    pub thickness_mm: f64,
}

/// The resistance to volume loss ([`fem::CompressionPenalty`]).
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct CompressionPenaltyReport {
    pub onset_volume_ratio: f64,
    pub lambda_multiple: f64,
}

impl From<fem::Material> for MaterialReport {
    fn from(material: fem::Material) -> MaterialReport {
        MaterialReport {
            young_kpa: material.young_kpa,
            poisson_ratio: material.poisson_ratio,
            density_kg_m3: material.density_kg_m3,
        }
    }
}

/// The materials of the simulation.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct MaterialsReport {
    pub tissue: MaterialReport,
    pub implant: MaterialReport,
    /// The skin over the tissue; `null`: homogeneous tissue up to the surface (older
    /// results and `--no-skin`).
    #[serde(default)]
    pub skin: Option<SkinReport>,
    /// The pectoralis major's elements; `null`: breast tissue there too (older results
    /// and `--no-muscle`).
    #[serde(default)]
    pub muscle: Option<MaterialReport>,
    /// The gel the implant was released as after the template's push (`--implant-gel-kpa`,
    /// experimental); `null`: the template's prescribed implant.
    #[serde(default)]
    pub implant_gel: Option<MaterialReport>,
    /// `null`: the paper's corotated energy (older results and
    /// `--no-compression-penalty`).
    #[serde(default)]
    pub compression_penalty: Option<CompressionPenaltyReport>,
}

impl MaterialsReport {
    pub(super) fn new(options: &SimulationOptions) -> MaterialsReport {
        let tissue = options.tissue;
        MaterialsReport {
            tissue: MaterialReport::from(tissue),
            implant: MaterialReport::from(options.soft_implant()),
            muscle: options.muscle.map(MaterialReport::from),
            implant_gel: options.implant_gel.map(MaterialReport::from),
            skin: options.skin.map(|skin| SkinReport {
                young_kpa: skin.young_kpa,
                thickness_mm: skin.thickness_mm,
            }),
            compression_penalty: options.compression_penalty.map(|penalty| {
                CompressionPenaltyReport {
                    onset_volume_ratio: penalty.onset_volume_ratio,
                    lambda_multiple: penalty.lambda_multiple,
                }
            }),
        }
    }
}

/// The JSON of `simulate` and `result.json` (GUIDE section 5).
#[derive(Debug, Clone, Serialize)]
pub struct SimulateReport {
    /// The program that wrote the folder ([`crate::software`]).
    pub software: String,
    pub model: PathBuf,
    pub implants: PerSide<Option<ImplantSummary>>,
    /// Breast volumes after the simulation, over the chest wall (the pre-operative
    /// fill-in joined to the moved cut curve; ml), with the chest skin over an implant
    /// that lies in a pocket beyond the native breast.
    pub breast_volume_ml: PerSide<f64>,
    /// Breast volumes of the model before (ml).
    pub breast_volume_before_ml: PerSide<f64>,
    /// Breast volumes after the simulation over a fill-in rebuilt on the moved cut
    /// curve, as `model` measures the simulated scan along `simulated_control_points.json`
    /// (ml; `null` where none can be rebuilt). Lower than `breast_volume_ml` where the
    /// implant pushes the cut curve forwards.
    pub breast_volume_rebuilt_fill_ml: PerSide<Option<f64>>,
    /// Quadrant volumes of the simulated breasts (ml; `null` where the moved landmarks
    /// no longer bound quadrants).
    pub quadrant_volume_ml: PerSide<Option<QuadrantVolumes>>,
    /// The implants' volumes (ml; 0 on a side without implant).
    pub implant_volume_ml: PerSide<f64>,
    /// Clinical distances on the simulated scan.
    pub distances: Vec<crate::Distance>,
    pub solver: SolverReport,
    pub no_gravity: bool,
    /// Where the implants' default positions lay (`footprint-centre`, `behind-nipple`).
    pub anchor: AnchorRule,
    /// The pockets' limits (`null`: the paper's bed, the fill-in alone).
    pub pocket: Option<PerSide<PocketReport>>,
    /// Nipple to the fold's lowest point (PSMF), straight (mm): before, as planned (before
    /// plus the fold lowering) and on the simulated scan (the landmark carried with the
    /// tissue).
    pub nipple_to_fold_mm: PerSide<NippleToFold>,
    pub materials: MaterialsReport,
    pub out_dir: PathBuf,
    pub files: Vec<String>,
}

/// A pocket's limits as `result.json` records them (see [`simulation::pocket`]).
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct PocketReport {
    /// Reach beyond the native breast's cut curve (mm, along the skin).
    pub margin_mm: f64,
    /// Distance kept from the sternal midline (mm).
    pub midline_clearance_mm: f64,
    /// Reach beyond the lateral end of the fold, towards the anterior axillary line (mm).
    pub lateral_beyond_fold_mm: f64,
    /// The planned fold lowering of the implant in the pocket (mm; 0 where it lies on
    /// the fill-in's bed).
    pub fold_lowering_mm: f64,
    /// Where the lowering comes from. Absent from folders written before it existed
    /// (given then).
    #[serde(default)]
    pub fold_lowering_rule: FoldLoweringRule,
}

/// Where a planned fold lowering comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FoldLoweringRule {
    /// The ICE principle for the implant (see [`simulation::pocket::ice_fold_lowering_mm`]).
    Ice,
    /// Given by the user (`--lower-fold-left`, `--lower-fold-right`).
    #[default]
    Given,
}

impl PocketReport {
    /// The record of `limits` with the fold lowering an implant got (mm).
    pub fn new(limits: &PocketLimits, fold_lowering_mm: f64) -> PocketReport {
        PocketReport {
            margin_mm: limits.margin_mm,
            midline_clearance_mm: limits.midline_clearance_mm,
            lateral_beyond_fold_mm: limits.lateral_beyond_fold_mm,
            fold_lowering_mm,
            fold_lowering_rule: match limits.fold_lowering {
                FoldLowering::ForImplant => FoldLoweringRule::Ice,
                FoldLowering::Mm(_) => FoldLoweringRule::Given,
            },
        }
    }
}

/// Nipple to fold distances of one side (mm, straight).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct NippleToFold {
    pub before_mm: f64,
    /// The distance before plus the fold lowering.
    pub planned_mm: f64,
    /// From the moved nipple to the simulated fold
    /// ([`simulation::Simulation::simulated_fold`]; to the carried PSMF landmark where no
    /// skin moved forward on its section).
    pub simulated_mm: f64,
    /// How far the simulated fold lies below the native one (mm, standing frame);
    /// `null` where no skin moved forward on its section.
    pub simulated_fold_lowering_mm: Option<f64>,
}

impl NippleToFold {
    pub(super) fn new(
        side: Side,
        simulation: &simulation::Simulation,
        before: &Landmarks,
        after: &Landmarks,
        lowering_mm: f64,
    ) -> NippleToFold {
        use anatomy::LandmarkName::{PSMFl, PSMFr, Pnl, Pnr};
        let (nipple, fold) = match side {
            Side::Left => (Pnl, PSMFl),
            Side::Right => (Pnr, PSMFr),
        };
        let before_mm = before.get(nipple).distance(before.get(fold));
        let simulated_fold = simulation.simulated_fold(side);
        let frame = simulation.frame();
        NippleToFold {
            before_mm,
            planned_mm: before_mm + lowering_mm,
            simulated_mm: after
                .get(nipple)
                .distance(simulated_fold.unwrap_or_else(|| after.get(fold))),
            simulated_fold_lowering_mm: simulated_fold
                .map(|p| frame.to_local(before.get(fold)).y - frame.to_local(p).y),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 222 ml implant of which `covered_ml` lie over the mesh and `template_ml` are
    /// inserted by its template.
    fn summary(covered_ml: f64, template_ml: f64) -> ImplantSummary {
        let shape = ImplantShape::from(implant::RoundImplant::new(115.0, 38.0).unwrap());
        ImplantSummary {
            spec: "catalog:R-MOD-115".into(),
            catalog_id: None,
            family: None,
            shape,
            width_mm: 115.0,
            height_mm: 115.0,
            projection_mm: 38.0,
            volume_ml: 222.0,
            template_volume_ml: template_ml,
            template_scale: 1.0,
            covered_volume_ml: covered_ml,
            rim_smoothing_mm: 14.0,
            template_layer_mm: 7.0,
            sliding_skin_vertices: 0,
            move_mm: [0.0; 3],
            rotation_deg: 0.0,
            fit_shift_mm: [0.0; 2],
            fold_lowering_mm: 0.0,
            anchor_mm: [0.0; 3],
        }
    }

    /// 5% of 222 ml is 11.1 ml: 11 ml left out by either cause is quiet, 12 ml is
    /// named, each cause with its own figures, both together in one warning.
    #[test]
    fn a_prediction_that_leaves_out_a_twentieth_of_the_implant_says_which_part() {
        assert_eq!(summary(222.0, 222.0).left_out(), None);
        assert_eq!(summary(211.0, 211.0).left_out(), None);
        assert_eq!(summary(222.0, 211.0).left_out(), None);
        // the bound is a share of the implant, not of the covered part: 11 ml is over 5% of
        // 212 ml (10.6) but not of 222
        assert_eq!(summary(212.0, 201.0).left_out(), None);
        let beyond = summary(210.0, 210.0).left_out().unwrap();
        assert!(
            beyond.starts_with("12 of its 222 ml lie beyond"),
            "{beyond}"
        );
        assert!(!beyond.contains("planned fold"), "{beyond}");
        let short = summary(222.0, 210.0).left_out().unwrap();
        assert!(
            short.starts_with("its displacement template inserts only 210 of the 222 ml"),
            "{short}"
        );
        let both = summary(210.0, 190.0).left_out().unwrap();
        assert!(
            both.contains("12 of its 222 ml") && both.contains("only 190 of the 210 ml"),
            "{both}"
        );
    }
}
