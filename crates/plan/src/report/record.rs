//! What the report reads back from a simulation folder's `result.json`, and the check
//! that its numbers are ones a simulation can give.

use super::*;

/// What the report reads back from `result.json`.
#[derive(Debug, Deserialize)]
pub(super) struct SimulationRecord {
    pub(super) model: PathBuf,
    pub(super) implants: PerSide<Option<ImplantRecord>>,
    pub(super) breast_volume_ml: PerSide<f64>,
    /// Absent from folders written before it existed.
    #[serde(default)]
    pub(super) quadrant_volume_ml: PerSide<Option<QuadrantVolumes>>,
    pub(super) distances: Vec<Distance>,
    pub(super) solver: SolverRecord,
    pub(super) no_gravity: bool,
    /// Absent from folders written before it existed: the only rule then.
    #[serde(default = "footprint_centre")]
    pub(super) anchor: AnchorRule,
    /// Absent from folders written before it existed (no pocket then).
    #[serde(default)]
    pub(super) pocket: Option<PerSide<crate::simulate::PocketReport>>,
    pub(super) materials: MaterialsReport,
}

#[derive(Debug, Deserialize)]
pub(super) struct ImplantRecord {
    pub(super) spec: String,
    pub(super) catalog_id: Option<String>,
    pub(super) family: Option<String>,
    pub(super) shape: ShapeRecord,
    pub(super) width_mm: f64,
    pub(super) height_mm: f64,
    pub(super) projection_mm: f64,
    pub(super) volume_ml: f64,
    pub(super) move_mm: [f64; 3],
    pub(super) rotation_deg: f64,
    pub(super) fit_shift_mm: [f64; 2],
}

/// The implant shape's kind and variant in `result.json`.
#[derive(Debug, Deserialize)]
pub(super) struct ShapeRecord {
    pub(super) shape: String,
    pub(super) profile: Option<String>,
    pub(super) taper: Option<String>,
}

#[derive(Debug, Deserialize)]
pub(super) struct SolverRecord {
    pub(super) vcycles: usize,
    pub(super) relative_residual: f64,
    pub(super) converged: bool,
    pub(super) inverted_elements: usize,
}

/// Reads `result.json`; its numbers must be ones a simulation can give.
pub(super) fn read_simulation_record(simulation_dir: &Path) -> Result<SimulationRecord> {
    let record: SimulationRecord =
        read_folder_json(simulation_dir, "result.json", "simulation", "simulate")?;
    record
        .check()
        .finish(&simulation_dir.join("result.json"), "mammaplan simulate")?;
    Ok(record)
}

impl SimulationRecord {
    /// The first number out of the range any simulation gives, by its field.
    pub(super) fn check(&self) -> FieldCheck {
        let mut check = FieldCheck::default();
        check.breast_volumes(&self.breast_volume_ml, |side| {
            self.quadrant_volume_ml.get(side).as_ref()
        });
        for (k, distance) in self.distances.iter().enumerate() {
            let lengths = [
                Some(("euclidean_mm", distance.euclidean_mm)),
                distance.surface_mm.map(|mm| ("surface_mm", mm)),
                distance.geodesic_mm.map(|mm| ("geodesic_mm", mm)),
            ];
            check.values(
                &format!("distances[{k}]"),
                lengths.into_iter().flatten(),
                &LENGTH_MM,
                "mm",
            );
        }
        for side in Side::BOTH {
            let Some(implant) = self.implants.get(side) else {
                continue;
            };
            let field = format!("implants.{side}");
            check
                .values(
                    &field,
                    [
                        ("width_mm", implant.width_mm),
                        ("height_mm", implant.height_mm),
                        ("projection_mm", implant.projection_mm),
                    ],
                    &LENGTH_MM,
                    "mm",
                )
                .values(&field, [("volume_ml", implant.volume_ml)], &VOLUME_ML, "ml")
                .values(
                    &field,
                    [
                        ("move_mm[0]", implant.move_mm[0]),
                        ("move_mm[1]", implant.move_mm[1]),
                        ("move_mm[2]", implant.move_mm[2]),
                        ("fit_shift_mm[0]", implant.fit_shift_mm[0]),
                        ("fit_shift_mm[1]", implant.fit_shift_mm[1]),
                    ],
                    &SHIFT_MM,
                    "mm",
                )
                .values(
                    &field,
                    [("rotation_deg", implant.rotation_deg)],
                    &(-360.0..=360.0),
                    "degrees",
                );
        }
        for (name, material) in [
            ("materials.tissue", &self.materials.tissue),
            ("materials.implant", &self.materials.implant),
        ] {
            check
                .values(
                    name,
                    [("young_kpa", material.young_kpa)],
                    &(f64::MIN_POSITIVE..=1e9),
                    "kPa",
                )
                .values(
                    name,
                    [("poisson_ratio", material.poisson_ratio)],
                    &(0.0..=0.4999),
                    "",
                )
                .values(
                    name,
                    [("density_kg_m3", material.density_kg_m3)],
                    &(f64::MIN_POSITIVE..=1e5),
                    "kg/m³",
                );
        }
        check.values(
            "solver",
            [("relative_residual", self.solver.relative_residual)],
            &(0.0..=f64::MAX),
            "",
        );
        check
    }
}
