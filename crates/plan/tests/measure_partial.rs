//! Live measuring (the GUI's path): the prepared surface measures a partial landmark set
//! exactly as the full `measure` does for the pairs it has.

use anatomy::measure::DistanceSpec;
use anatomy::{LandmarkName, PartialLandmarks};
use plan::measure::{MeasuringSurface, measure};
use plan::{MarkedScan, PhantomParams, Silent};

#[test]
fn a_partial_set_measures_like_the_full_one() {
    let marked = MarkedScan::phantom(&PhantomParams::default()).unwrap();
    assert!(
        marked
            .scan
            .path
            .display()
            .to_string()
            .starts_with("phantom (cup=medium")
    );
    let full = measure(&marked, &[], &Silent).unwrap();

    let mut partial = PartialLandmarks::default();
    for name in [
        LandmarkName::Pj,
        LandmarkName::Px,
        LandmarkName::Pcl,
        LandmarkName::Pcr,
        LandmarkName::Pnl,
    ] {
        partial.set(name, marked.landmarks.get(name));
    }
    let frame = partial.frame(None).unwrap().unwrap();
    assert_eq!(frame, marked.frame);
    let surface = MeasuringSurface::new(&marked.scan, &Silent).unwrap();
    let specs = [
        DistanceSpec::between("Pcl", "Pnl"),
        DistanceSpec::between("Pj", "Pnl"),
    ];
    let live = surface.distances(&frame, &partial, &specs).unwrap();
    for distance in &live {
        let reference = full
            .distances
            .iter()
            .find(|d| d.name == distance.name)
            .unwrap();
        assert_eq!(distance, reference);
        assert!(distance.geodesic_mm.unwrap() > 100.0, "{distance:?}");
    }
    let error = surface
        .distances(&frame, &partial, &[DistanceSpec::between("Pnl", "Pnr")])
        .unwrap_err();
    assert!(error.to_string().contains("\"Pnr\""), "{error}");
}
