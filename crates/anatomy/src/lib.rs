//! Anatomy on a surface scan: landmarks (reading, validating, snapping), the anatomical
//! frame, clinical measurements and rigid registration of two scans.
//!
//! Works on [`mesh::TriMesh`]; knows nothing about finite elements or implants.

pub mod breast;
pub mod closed_surface;
pub mod fill_in;
pub mod frame;
pub mod landmarks;
pub mod measure;
pub mod place;
pub mod register;
pub mod scan_holes;
mod wall_clearance;

pub use breast::{
    Breast, BreastError, BreastModel, BreastOptions, ControlPoints, QuadrantVolumes, Side,
    build_breast_model,
};
pub use closed_surface::{
    ClipBox, ClipBoxFit, ClosedSurface, ClosedSurfaceError, ClosedSurfaceOptions, GrazingPlane,
    SurfaceRole, build_closed_surface, build_closed_surface_in_box,
};
pub use fill_in::{FillIn, FillInError, FillInParams, fill_hole, stitch};
pub use frame::{AnatomicalFrame, FrameError, SideError, Up, UpSource};
pub use landmarks::{
    LandmarkError, LandmarkName, Landmarks, NamedPoints, ON_SURFACE_MM, PartialLandmarks,
    SnapWarning,
};
