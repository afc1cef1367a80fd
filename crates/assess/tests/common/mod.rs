//! The phantom with its breast model, shared by the tests.

// Each test file uses a part of it.
#![allow(dead_code)]

use anatomy::{AnatomicalFrame, BreastModel, BreastOptions, Up, build_breast_model};
use mesh::{SurfaceIndex, Topology};
use phantom::{Phantom, PhantomParams};

/// A phantom scan prepared for assessment.
pub struct MarkedPhantom {
    pub phantom: Phantom,
    pub index: SurfaceIndex,
    pub topology: Topology,
    pub frame: AnatomicalFrame,
    pub breasts: BreastModel,
}

/// The phantom of `params` with its BVH, topology, frame and breast model.
pub fn marked_phantom(params: &PhantomParams) -> MarkedPhantom {
    let phantom = phantom::generate(params);
    let (index, topology) = (
        SurfaceIndex::new(&phantom.scan).unwrap(),
        Topology::new(&phantom.scan),
    );
    let frame = AnatomicalFrame::from_landmarks(&phantom.landmarks, Up::FILE_VERTICAL).unwrap();
    let breasts = build_breast_model(
        &phantom.scan,
        &topology,
        &index,
        &frame.sternal(),
        &phantom.landmarks,
        &BreastOptions::default(),
    )
    .unwrap();
    MarkedPhantom {
        phantom,
        index,
        topology,
        frame,
        breasts,
    }
}
