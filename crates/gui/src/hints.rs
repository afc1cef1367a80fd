//! Where each required landmark is, in words for the surgeon placing it (paper Fig. 2).

use anatomy::LandmarkName;

/// A one-sentence hint of where to click for a landmark. Left and right are the
/// patient's: in the front view the patient's left is on the screen's right.
pub fn hint(name: LandmarkName) -> &'static str {
    match name {
        LandmarkName::Pj => {
            "Sternal notch (jugulum): the dip in the midline at the top of the sternum, between the inner ends of the clavicles."
        }
        LandmarkName::Pcl => {
            "Left clavicle: on the patient's left collarbone, halfway along it (screen right in the front view)."
        }
        LandmarkName::Pcr => {
            "Right clavicle: on the patient's right collarbone, halfway along it (screen left in the front view)."
        }
        LandmarkName::Pnl => "Left nipple: the tip of the patient's left nipple.",
        LandmarkName::Pnr => "Right nipple: the tip of the patient's right nipple.",
        LandmarkName::PSMFl => {
            "Left fold, lowest point: the lowest point of the crease under the left breast."
        }
        LandmarkName::PSMFr => {
            "Right fold, lowest point: the lowest point of the crease under the right breast."
        }
        LandmarkName::PSMFml => {
            "Left fold, medial end: where the crease under the left breast ends towards the sternum."
        }
        LandmarkName::PSMFmr => {
            "Right fold, medial end: where the crease under the right breast ends towards the sternum."
        }
        LandmarkName::PSMFll => {
            "Left fold, lateral end: where the left breast meets the chest wall at the side, about level with the nipple."
        }
        LandmarkName::PSMFlr => {
            "Right fold, lateral end: where the right breast meets the chest wall at the side, about level with the nipple."
        }
        LandmarkName::Px => {
            "Xiphoid: the lower tip of the sternum, in the midline between and below the breasts."
        }
    }
}
