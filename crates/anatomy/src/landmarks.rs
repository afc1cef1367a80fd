//! Anatomical landmarks (paper Fig. 2) and the landmark file format of the GUIDE:
//! `{"units":"mm","landmarks":{"Pj":[x,y,z],...},"extra":{"name":[x,y,z]}}`.

use glam::DVec3;
use std::collections::BTreeMap;

/// The twelve required landmarks. Suffix `l`/`r` is the patient's left/right.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum LandmarkName {
    /// Sternal notch (jugulum).
    Pj,
    /// Mid-clavicular point, left.
    Pcl,
    /// Mid-clavicular point, right.
    Pcr,
    /// Nipple, left.
    Pnl,
    /// Nipple, right.
    Pnr,
    /// Lowest point of the inframammary fold, left.
    PSMFl,
    /// Lowest point of the inframammary fold, right.
    PSMFr,
    /// Medial end of the fold, left.
    PSMFml,
    /// Medial end of the fold, right.
    PSMFmr,
    /// Lateral end of the fold, left.
    PSMFll,
    /// Lateral end of the fold, right.
    PSMFlr,
    /// Xiphoid.
    Px,
}

impl LandmarkName {
    /// All required landmarks in file order.
    pub const ALL: [LandmarkName; 12] = [
        LandmarkName::Pj,
        LandmarkName::Pcl,
        LandmarkName::Pcr,
        LandmarkName::Pnl,
        LandmarkName::Pnr,
        LandmarkName::PSMFl,
        LandmarkName::PSMFr,
        LandmarkName::PSMFml,
        LandmarkName::PSMFmr,
        LandmarkName::PSMFll,
        LandmarkName::PSMFlr,
        LandmarkName::Px,
    ];

    /// The name as written in files and reports (`"Pj"`, `"PSMFl"`, ...).
    pub fn as_str(self) -> &'static str {
        match self {
            LandmarkName::Pj => "Pj",
            LandmarkName::Pcl => "Pcl",
            LandmarkName::Pcr => "Pcr",
            LandmarkName::Pnl => "Pnl",
            LandmarkName::Pnr => "Pnr",
            LandmarkName::PSMFl => "PSMFl",
            LandmarkName::PSMFr => "PSMFr",
            LandmarkName::PSMFml => "PSMFml",
            LandmarkName::PSMFmr => "PSMFmr",
            LandmarkName::PSMFll => "PSMFll",
            LandmarkName::PSMFlr => "PSMFlr",
            LandmarkName::Px => "Px",
        }
    }

    /// Parses a file name of a landmark (exact spelling).
    pub fn parse(name: &str) -> Option<LandmarkName> {
        LandmarkName::ALL.into_iter().find(|n| n.as_str() == name)
    }
}

/// A complete set of landmarks in one scan's file frame (mm): the twelve required ones
/// and any number of named extra points.
#[derive(Debug, Clone, PartialEq)]
pub struct Landmarks {
    required: [DVec3; 12],
    /// User-defined points by name.
    pub extra: BTreeMap<String, DVec3>,
}

impl Landmarks {
    /// Builds a set from a position for every required landmark.
    pub fn new(position: impl Fn(LandmarkName) -> DVec3) -> Landmarks {
        Landmarks {
            required: LandmarkName::ALL.map(position),
            extra: BTreeMap::new(),
        }
    }

    /// Position of a required landmark (mm).
    pub fn get(&self, name: LandmarkName) -> DVec3 {
        self.required[name as usize]
    }

    /// Moves a required landmark.
    pub fn set(&mut self, name: LandmarkName, position: DVec3) {
        self.required[name as usize] = position;
    }

    /// Looks a point up by its file name, required or extra.
    pub fn lookup(&self, name: &str) -> Option<DVec3> {
        LandmarkName::parse(name)
            .map(|n| self.get(n))
            .or_else(|| self.extra.get(name).copied())
    }

    /// Every point with its name: required ones first, then extras.
    pub fn iter(&self) -> impl Iterator<Item = (&str, DVec3)> + '_ {
        LandmarkName::ALL
            .into_iter()
            .map(|n| (n.as_str(), self.get(n)))
            .chain(self.extra.iter().map(|(k, v)| (k.as_str(), *v)))
    }

    /// Applies `f` to every point (required and extra), e.g. a rigid transform.
    pub fn map_positions(&mut self, f: impl Fn(DVec3) -> DVec3) {
        for p in &mut self.required {
            *p = f(*p);
        }
        for p in self.extra.values_mut() {
            *p = f(*p);
        }
    }
}
