//! What the viewport shows: the window's display modes, which panels and scripts choose.

/// What the viewport shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DisplayMode {
    /// The scan as loaded (landmarks and cut curves on it).
    PreOperative,
    /// The predicted post-operative scan.
    Simulated,
    /// The scan as loaded with the prediction over it, translucent.
    Overlay,
    /// The prediction coloured by its distance from the scan as loaded (paper Fig. 3).
    Deviation,
    /// The registered post-operative scan, coloured by its distance from the scan as
    /// loaded or from the prediction.
    PostOperative,
}

impl DisplayMode {
    pub(crate) const ALL: [DisplayMode; 5] = [
        DisplayMode::PreOperative,
        DisplayMode::Simulated,
        DisplayMode::Overlay,
        DisplayMode::Deviation,
        DisplayMode::PostOperative,
    ];

    pub(crate) fn label(self) -> &'static str {
        match self {
            DisplayMode::PreOperative => "Pre-operative",
            DisplayMode::Simulated => "Simulated",
            DisplayMode::Overlay => "Overlay",
            DisplayMode::Deviation => "Deviation",
            DisplayMode::PostOperative => "Post-operative",
        }
    }
}
