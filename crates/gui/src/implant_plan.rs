//! The implants being planned: per side a catalog entry or custom dimensions, a move and
//! a turn from the default position; or both sides linked, the right mirroring the left.
//! Plain state with the editing rules, no egui; shapes, volumes, specs and suggestions
//! come from `plan`'s catalog.

use anatomy::breast::Side;
use glam::DVec3;
use plan::catalog::{
    AnatomicImplant, Catalog, ImplantShape, ImplantSpec, RoundImplant, ShapeKind, SuggestTarget,
};
use plan::model::PerSide;
use plan::simulate::ImplantRequest;

/// Default step of the move buttons (mm).
pub const DEFAULT_STEP_MM: f64 = 5.0;
/// The catalog entry a side starts with.
pub const DEFAULT_CATALOG_ID: &str = "R-MOD-120";

/// Where a side's implant comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    Catalog,
    /// Width, height and projection set by hand.
    Custom,
}

/// One side's implant as edited.
#[derive(Debug, Clone, PartialEq)]
pub struct ImplantDesign {
    /// Whether this side gets an implant.
    pub enabled: bool,
    pub source: Source,
    pub catalog_id: String,
    /// Custom dimensions (mm); a round implant's diameter is its width.
    pub kind: ShapeKind,
    pub width_mm: f64,
    pub height_mm: f64,
    pub projection_mm: f64,
    /// Move from the default position (mm, anatomical frame: `x` to the patient's
    /// left, `y` up, `z` anterior).
    pub move_mm: DVec3,
    /// Turn about the chest wall's normal, counter-clockwise seen from the front
    /// (degrees).
    pub rotation_deg: f64,
    /// How far the fold is lowered for this implant (mm); `None`: as the ICE principle
    /// plans it for the implant.
    pub fold_lowering_mm: Option<f64>,
}

impl Default for ImplantDesign {
    /// No implant; the default catalog entry chosen, its dimensions (those of the
    /// built-in `R-MOD-120`) ready as custom ones.
    fn default() -> ImplantDesign {
        ImplantDesign {
            enabled: false,
            source: Source::Catalog,
            catalog_id: DEFAULT_CATALOG_ID.into(),
            kind: ShapeKind::Round,
            width_mm: 120.0,
            height_mm: 113.0,
            projection_mm: 33.5,
            move_mm: DVec3::ZERO,
            rotation_deg: 0.0,
            fold_lowering_mm: None,
        }
    }
}

impl ImplantDesign {
    /// The shape: the catalog entry's, or the custom dimensions'. Errors say what is wrong
    /// (an unknown id, dimensions that make no implant).
    pub fn shape(&self, catalog: &Catalog) -> Result<ImplantShape, String> {
        match self.source {
            Source::Catalog => catalog
                .get(&self.catalog_id)
                .map(|entry| *entry.shape())
                .ok_or_else(|| format!("no catalog entry {}", self.catalog_id)),
            Source::Custom => match self.kind {
                ShapeKind::Round => {
                    RoundImplant::new(self.width_mm, self.projection_mm).map(ImplantShape::from)
                }
                ShapeKind::Anatomic => {
                    AnatomicImplant::new(self.width_mm, self.height_mm, self.projection_mm)
                        .map(ImplantShape::from)
                }
            }
            .map_err(|error| error.to_string()),
        }
    }

    /// The implant spec (`catalog:ID`, or the custom shape's canonical spec).
    pub fn spec(&self, catalog: &Catalog) -> Result<String, String> {
        match self.source {
            Source::Catalog => self
                .shape(catalog)
                .map(|_| format!("catalog:{}", self.catalog_id)),
            Source::Custom => self.shape(catalog).map(|shape| shape.to_string()),
        }
    }

    /// What the simulation is asked for: `None` without implant.
    pub fn request(&self, catalog: &Catalog) -> Result<Option<ImplantRequest>, String> {
        if !self.enabled {
            return Ok(None);
        }
        Ok(Some(ImplantRequest {
            spec: self.spec(catalog)?,
            move_mm: self.move_mm,
            rotation_deg: self.rotation_deg,
            fold_lowering_mm: self.fold_lowering_mm,
        }))
    }

    /// The design of a request (a planning case's): a catalog id or a custom shape.
    /// Errors: a spec that does not parse.
    pub fn from_request(request: &ImplantRequest, catalog: &Catalog) -> Result<Self, String> {
        let mut design = ImplantDesign {
            enabled: true,
            move_mm: request.move_mm,
            rotation_deg: request.rotation_deg,
            fold_lowering_mm: request.fold_lowering_mm,
            ..ImplantDesign::default()
        };
        let shape = match ImplantSpec::parse(&request.spec).map_err(|e| e.to_string())? {
            ImplantSpec::Catalog(id) => {
                design.source = Source::Catalog;
                let shape = catalog.get(&id).map(|entry| *entry.shape());
                design.catalog_id = id;
                shape
            }
            ImplantSpec::Shape(shape) => {
                design.source = Source::Custom;
                Some(shape)
            }
        };
        // The custom dimensions follow the shape, so switching to "custom" starts there.
        if let Some(shape) = shape {
            design.set_dimensions(&shape);
        }
        Ok(design)
    }

    /// Sets the custom dimensions to a shape's.
    pub fn set_dimensions(&mut self, shape: &ImplantShape) {
        self.kind = shape.kind();
        self.width_mm = shape.width_mm();
        if shape.kind() == ShapeKind::Anatomic {
            self.height_mm = shape.height_mm();
        }
        self.projection_mm = shape.projection_mm();
    }

    /// Chooses a catalog entry (its dimensions become the custom ones too).
    pub fn choose(&mut self, id: &str, catalog: &Catalog) {
        self.source = Source::Catalog;
        self.catalog_id = id.to_string();
        if let Some(entry) = catalog.get(id) {
            self.set_dimensions(entry.shape());
        }
    }

    /// The catalog entry of the same kind closest to the custom dimensions
    /// ([`Catalog::suggest`]: width, height for anatomic implants, projection counted
    /// twice): its id.
    pub fn suggest(&self, catalog: &Catalog) -> Result<String, String> {
        let target = SuggestTarget::Dimensions {
            width_mm: self.width_mm,
            height_mm: (self.kind == ShapeKind::Anatomic).then_some(self.height_mm),
            projection_mm: self.projection_mm,
        };
        let best = catalog
            .suggest(&target, Some(self.kind), 1)
            .map_err(|error| error.to_string())?;
        best.first()
            .map(|s| s.entry.id().to_string())
            .ok_or_else(|| format!("the catalog has no {} implant", self.kind))
    }

    /// The design mirrored across the midline: the move to the patient's left becomes
    /// one to the right, the turn goes the other way (`0 - x`, so that no `-0` turns up
    /// in saved cases).
    pub fn mirrored(&self) -> ImplantDesign {
        ImplantDesign {
            move_mm: DVec3::new(0.0 - self.move_mm.x, self.move_mm.y, self.move_mm.z),
            rotation_deg: 0.0 - self.rotation_deg,
            ..self.clone()
        }
    }
}

/// A move button (paper Fig. 10), in the anatomical frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MoveDirection {
    /// Towards the patient's left (screen right in the front view).
    Left,
    Right,
    Up,
    Down,
    /// Anterior: the implant lies shallower.
    Front,
    /// Posterior: deeper.
    Back,
}

impl MoveDirection {
    pub const ALL: [MoveDirection; 6] = [
        MoveDirection::Left,
        MoveDirection::Right,
        MoveDirection::Up,
        MoveDirection::Down,
        MoveDirection::Front,
        MoveDirection::Back,
    ];

    /// The unit move in the anatomical frame.
    pub fn unit(self) -> DVec3 {
        match self {
            MoveDirection::Left => DVec3::X,
            MoveDirection::Right => DVec3::NEG_X,
            MoveDirection::Up => DVec3::Y,
            MoveDirection::Down => DVec3::NEG_Y,
            MoveDirection::Front => DVec3::Z,
            MoveDirection::Back => DVec3::NEG_Z,
        }
    }

    /// The button's label.
    pub fn label(self) -> &'static str {
        match self {
            MoveDirection::Left => "Move left",
            MoveDirection::Right => "Move right",
            MoveDirection::Up => "Move up",
            MoveDirection::Down => "Move down",
            MoveDirection::Front => "Move front",
            MoveDirection::Back => "Move back",
        }
    }
}

/// Which side the implant panel edits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Editing {
    Side(Side),
    /// Both sides at once: the left is edited, the right mirrors it.
    Linked,
}

/// Both sides' implants.
#[derive(Debug, Clone, PartialEq)]
pub struct ImplantPlan {
    pub designs: PerSide<ImplantDesign>,
    pub editing: Editing,
    /// Length of one press of a move button (mm).
    pub step_mm: f64,
    /// Whether the gravity correction follows the implant stage.
    pub gravity: bool,
}

impl Default for ImplantPlan {
    fn default() -> ImplantPlan {
        ImplantPlan {
            designs: PerSide::default(),
            editing: Editing::Linked,
            step_mm: DEFAULT_STEP_MM,
            gravity: true,
        }
    }
}

impl ImplantPlan {
    /// Whether the right side mirrors the left.
    pub fn linked(&self) -> bool {
        self.editing == Editing::Linked
    }

    /// The design the panel edits (the left one when linked).
    pub fn edited(&mut self) -> &mut ImplantDesign {
        match self.editing {
            Editing::Side(side) => self.designs.get_mut(side),
            Editing::Linked => &mut self.designs.left,
        }
    }

    /// Switches the panel to another side or to both; linking makes the right side the
    /// mirror of the left, unlinking keeps the mirror as the right side's own design.
    pub fn edit(&mut self, editing: Editing) {
        if self.linked() || editing == Editing::Linked {
            self.designs.right = self.designs.left.mirrored();
        }
        self.editing = editing;
    }

    /// The design of one side as simulated (linked: the right mirrors the left).
    pub fn design(&self, side: Side) -> ImplantDesign {
        match (side, self.linked()) {
            (Side::Right, true) => self.designs.left.mirrored(),
            _ => self.designs.get(side).clone(),
        }
    }

    /// One press of a move button on the edited design.
    pub fn step(&mut self, direction: MoveDirection) {
        let step = self.step_mm * direction.unit();
        self.edited().move_mm += step;
    }

    /// What the simulation is asked for on both sides; an error names the side whose
    /// design makes no implant.
    pub fn requests(&self, catalog: &Catalog) -> Result<PerSide<Option<ImplantRequest>>, String> {
        let request = |side: Side| {
            self.design(side)
                .request(catalog)
                .map_err(|error| format!("{side} implant: {error}"))
        };
        Ok(PerSide {
            left: request(Side::Left)?,
            right: request(Side::Right)?,
        })
    }

    /// The plan of a planning case's implants.
    pub fn from_requests(
        implants: &PerSide<Option<ImplantRequest>>,
        linked: bool,
        gravity: bool,
        catalog: &Catalog,
    ) -> Result<ImplantPlan, String> {
        let design = |side: Side| match implants.get(side) {
            Some(request) => ImplantDesign::from_request(request, catalog)
                .map_err(|error| format!("{side} implant: {error}")),
            None => Ok(ImplantDesign::default()),
        };
        Ok(ImplantPlan {
            designs: PerSide {
                left: design(Side::Left)?,
                right: design(Side::Right)?,
            },
            editing: if linked {
                Editing::Linked
            } else {
                Editing::Side(Side::Left)
            },
            gravity,
            ..ImplantPlan::default()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linked_sides_mirror_moves_and_turns_and_keep_them_when_unlinked() {
        let catalog = Catalog::builtin();
        let mut plan = ImplantPlan::default();
        plan.edited().enabled = true;
        plan.step(MoveDirection::Left);
        plan.step(MoveDirection::Up);
        plan.step(MoveDirection::Up);
        plan.step(MoveDirection::Back);
        plan.edited().rotation_deg = 10.0;
        plan.edited().fold_lowering_mm = Some(8.0);
        let requests = plan.requests(&catalog).unwrap();
        let left = requests.left.unwrap();
        let right = requests.right.unwrap();
        // the fold lowering is a depth below each side's own fold: the same on both
        assert_eq!(
            (left.fold_lowering_mm, right.fold_lowering_mm),
            (Some(8.0), Some(8.0))
        );
        assert_eq!(left.spec, "catalog:R-MOD-120");
        assert_eq!(right.spec, left.spec);
        // Known answer: one 5 mm step left, two up, one back.
        assert_eq!(left.move_mm, DVec3::new(5.0, 10.0, -5.0));
        assert_eq!(right.move_mm, DVec3::new(-5.0, 10.0, -5.0));
        assert_eq!((left.rotation_deg, right.rotation_deg), (10.0, -10.0));

        plan.edit(Editing::Side(Side::Right));
        plan.step(MoveDirection::Right);
        let requests = plan.requests(&catalog).unwrap();
        assert_eq!(requests.left.unwrap().move_mm, DVec3::new(5.0, 10.0, -5.0));
        assert_eq!(
            requests.right.unwrap().move_mm,
            DVec3::new(-10.0, 10.0, -5.0)
        );
    }

    #[test]
    fn custom_dimensions_give_specs_volumes_and_suggestions() {
        let catalog = Catalog::builtin();
        let mut design = ImplantDesign {
            enabled: true,
            source: Source::Custom,
            ..ImplantDesign::default()
        };
        design.width_mm = 115.0;
        design.projection_mm = 33.0;
        assert_eq!(
            design.spec(&catalog).unwrap(),
            "round:diameter=115,projection=33"
        );
        // Eq. 2's half ellipsoid: π w² p / 6.
        let volume_ml = design.shape(&catalog).unwrap().volume_ml();
        let expected_ml = std::f64::consts::PI * 115.0 * 115.0 * 33.0 / 6.0 / 1000.0;
        assert!((volume_ml - expected_ml).abs() < 1e-6 * expected_ml);
        // The catalog's moderate profile at 115 mm has a 32 mm projection (0.28 w).
        assert_eq!(design.suggest(&catalog).unwrap(), "R-MOD-115");
        // The default design's custom dimensions are its catalog entry's.
        let default = ImplantDesign::default();
        let entry = catalog.get(DEFAULT_CATALOG_ID).unwrap().shape();
        assert_eq!(
            (default.width_mm, default.projection_mm),
            (entry.width_mm(), entry.projection_mm())
        );

        design.projection_mm = 70.0;
        let error = design.request(&catalog).unwrap_err();
        assert!(error.contains("projection"), "{error}");

        let request = ImplantRequest::new("anatomic:width=120,height=113,projection=42");
        let anatomic = ImplantDesign::from_request(&request, &catalog).unwrap();
        assert_eq!(anatomic.source, Source::Custom);
        assert_eq!(anatomic.kind, ShapeKind::Anatomic);
        assert_eq!(anatomic.request(&catalog).unwrap(), Some(request));
        let from_catalog =
            ImplantDesign::from_request(&ImplantRequest::new("catalog:A-FF-120"), &catalog)
                .unwrap();
        assert_eq!(from_catalog.source, Source::Catalog);
        assert_eq!(from_catalog.kind, ShapeKind::Anatomic);
        assert_eq!(from_catalog.width_mm, 120.0);
    }
}
