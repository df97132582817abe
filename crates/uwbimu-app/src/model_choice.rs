//! What the model selection ([`crate::select`]) reports: the candidates it scored and the one it
//! chose. The types sit below the runner because a batch run's output carries the choice
//! ([`crate::methods::BatchOutput`]); [`crate::select`] re-exports them, their public path.

use uwbimu_vocabulary::config::{ConfigValue, FilterConfig};

/// A scored candidate.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// What it is, e.g. `"steady bias, symmetric test"` or `"as configured, range_std ×2"`.
    pub label: String,
    /// The settings it changes against the input configuration.
    pub overrides: Vec<(String, ConfigValue)>,
    /// Its held-out range RMS (the criterion of [`crate::select`]), m; +∞ when a run failed.
    pub score_m: f64,
    /// The held-out RMS per anchor, m (NaN for an anchor with too few scored ranges).
    pub per_anchor_m: Vec<f64>,
    /// The held-out RMS of each fold, m (+∞ for a fold whose run failed or scored nothing).
    pub per_fold_m: Vec<f64>,
}

/// What [`crate::select::choose`] decided.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelChoice {
    /// The configuration to run: the input with the chosen candidate's overrides and
    /// `model_selection.enabled` off, so that running it reproduces the choosing method's run.
    pub config: FilterConfig,
    /// Every candidate scored, in the order tried (the first is the input configuration); empty
    /// when no selection was possible.
    pub candidates: Vec<Candidate>,
    /// Index of the chosen candidate in `candidates`.
    pub chosen: usize,
    /// Why: the chosen candidate's score against the input's, or why no selection ran.
    pub reason: String,
}

impl ModelChoice {
    /// No selection: `config` as given, with `model_selection.enabled` off (as a choice's
    /// configuration), no candidates, and the reason `no selection: {why}`.
    pub fn kept(config: &FilterConfig, why: impl std::fmt::Display) -> Self {
        let mut config = config.clone();
        config.model_selection.enabled = false;
        Self { config, candidates: Vec::new(), chosen: 0, reason: format!("no selection: {why}") }
    }

    /// The chosen candidate (None when no selection ran).
    pub fn chosen(&self) -> Option<&Candidate> {
        self.candidates.get(self.chosen)
    }

    /// The settings the choice changes against the input configuration.
    pub fn overrides(&self) -> &[(String, ConfigValue)] {
        self.chosen().map_or(&[], |c| &c.overrides)
    }
}
