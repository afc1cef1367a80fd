//! Where a failed build's problem lies on the body: the place the first error in its
//! chain that knows one names (issue 21, item 6: the GUI rings it on the scan).

pub use anatomy::place::Place;
use anatomy::{BreastError, ClosedSurfaceError};
use mesh::CurveError;

/// The place of the first error in `error`'s chain that has one (mm, the scan's file
/// coordinates); `None` if none has.
pub fn failure_place(error: &anyhow::Error) -> Option<Place> {
    error.chain().find_map(|cause| {
        if let Some(breast) = cause.downcast_ref::<BreastError>() {
            breast.place()
        } else if let Some(closed) = cause.downcast_ref::<ClosedSurfaceError>() {
            closed.place()
        } else if let Some(curve) = cause.downcast_ref::<CurveError>() {
            curve.position().map(Place::at)
        } else {
            None
        }
    })
}
