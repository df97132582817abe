//! The anchor survey of a log of anchor-to-anchor ranges (`uwbimu-replay survey`): the ranges read
//! through the mapping ([`uwbimu_io::recordings::anchor_ranges`]), the known mounting heights by row or by id
//! ([`Heights`]), [`survey_anchors`] on them, and the residuals summed up per pair
//! ([`PairResiduals`]).

use std::collections::BTreeMap;
use std::path::Path;

use uwbimu_estimation::anchor_survey::{survey_anchors, AnchorSurvey, SurveyPriors};
use uwbimu_vocabulary::error::Error as CoreError;

use uwbimu_io::recordings::anchor_ranges::{read_anchor_ranges_file, AnchorRangeStats, AnchorRanges};
use uwbimu_io::{IoResult as Result, Mapping};

/// The mounting heights the user knows, m.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum Heights {
    /// None known.
    #[default]
    Unknown,
    /// One per anchor row, in row order (NaN where unknown).
    ByRow(Vec<f64>),
    /// By anchor id; the anchors not named are unknown.
    ById(BTreeMap<String, f64>),
}

impl Heights {
    /// Parses `2.4,2.6,nan,0.5` (one per anchor row, `nan` where unknown) or `A0=2.4,A3=0.5` (by
    /// id, the others unknown); blank text is [`Heights::Unknown`].
    ///
    /// # Errors
    /// [`CoreError::BadArgument`] (`heights`) for a value that is not a number, a mix of the two
    /// forms or an id given twice.
    pub fn parse(text: &str) -> Result<Self> {
        if text.trim().is_empty() {
            return Ok(Self::Unknown);
        }
        let items: Vec<&str> = text.split(',').map(str::trim).collect();
        let bad = |arg: &str, reason: &str| CoreError::BadArgument { call: "heights", arg: arg.into(), reason: reason.into() };
        let number = |s: &str| s.parse::<f64>().map_err(|_| bad(s, "is not a number (m; `nan` where unknown)"));
        let by_id = items.iter().filter(|s| s.contains('=')).count();
        if by_id == 0 {
            return Ok(Self::ByRow(items.into_iter().map(number).collect::<std::result::Result<_, _>>()?));
        }
        if by_id != items.len() {
            return Err(bad(text, "mixes `id=height` with plain heights: give one form").into());
        }
        let mut out = BTreeMap::new();
        for item in items {
            let (id, h) = item.split_once('=').unwrap_or((item, ""));
            if out.insert(id.trim().to_string(), number(h.trim())?).is_some() {
                return Err(bad(item, "names an anchor given before").into());
            }
        }
        Ok(Self::ById(out))
    }

    /// The height of each anchor row of `ids` (NaN where unknown); empty when none is known.
    ///
    /// # Errors
    /// [`CoreError::BadArgument`] (`heights`) for a count that is not the number of rows, or an id
    /// that is not an anchor's; the message lists the rows.
    pub fn per_row(&self, ids: &[String]) -> Result<Vec<f64>> {
        let rows = || ids.iter().enumerate().map(|(k, id)| format!("{k} = {id}")).collect::<Vec<_>>().join(", ");
        match self {
            Self::Unknown => Ok(Vec::new()),
            Self::ByRow(h) if h.len() == ids.len() => Ok(h.clone()),
            Self::ByRow(h) => Err(CoreError::BadArgument {
                call: "heights",
                arg: format!("{} values", h.len()),
                reason: format!("for {} anchors: give one per anchor row, in row order ({})", ids.len(), rows()),
            }
            .into()),
            Self::ById(by_id) => {
                if let Some(id) = by_id.keys().find(|id| !ids.contains(id)) {
                    return Err(CoreError::BadArgument {
                        call: "heights",
                        arg: format!("`{id}`"),
                        reason: format!("is not an anchor of the log (rows: {})", rows()),
                    }
                    .into());
                }
                Ok(ids.iter().map(|id| by_id.get(id).copied().unwrap_or(f64::NAN)).collect())
            }
        }
    }
}

/// The residuals `‖a_i − a_j‖ − m` of the ranges of one pair of anchor rows, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairResiduals {
    /// The lower anchor row.
    pub i: usize,
    /// The higher anchor row.
    pub j: usize,
    /// Ranges of the pair.
    pub count: usize,
    /// Median residual (negative: the ranges are longer than the survey, as in NLOS).
    pub median_m: f64,
    /// Root mean square residual.
    pub rms_m: f64,
    /// Largest absolute residual.
    pub max_abs_m: f64,
}

/// The surveyed anchors of a log.
#[derive(Debug, Clone, PartialEq)]
pub struct LogSurvey {
    /// The id of each anchor row (the rows of `survey.positions`).
    pub anchor_ids: Vec<String>,
    /// The survey ([`survey_anchors`]): positions, covariances, residuals per range, warnings
    /// (which name anchors by row), frame.
    pub survey: AnchorSurvey,
    /// The residuals per pair of rows, in row order.
    pub pairs: Vec<PairResiduals>,
    /// What reading found and dropped.
    pub stats: AnchorRangeStats,
}

/// Surveys the anchors of `ranges` with the known `heights`.
///
/// # Errors
/// [`CoreError::InsufficientData`] when no range is usable (the message says what was dropped),
/// and the errors of [`survey_anchors`] (too few pairs, an anchor row without pairs, a pair graph
/// in pieces), with the rows' ids added; the errors of [`Heights::per_row`].
pub fn survey_ranges(ranges: AnchorRanges, heights: &Heights) -> Result<LogSurvey> {
    let AnchorRanges { anchor_ids, pairs, stats } = ranges;
    if pairs.is_empty() {
        let topics: Vec<&str> =
            stats.topics.iter().filter(|t| t.role == uwbimu_io::TopicRole::AnchorRanges).map(|t| t.topic.as_str()).collect();
        let unknown: Vec<&str> = stats.unknown_ids.iter().map(String::as_str).collect();
        return Err(CoreError::InsufficientData(format!(
            "no usable anchor-to-anchor range on {}: {} decoded, {} not finite, negative or of one anchor with itself, \
             {} naming ids outside the anchor rows ({}; rows from {})",
            topics.join(", "),
            stats.decoded,
            stats.bad_value,
            stats.unknown_anchor,
            if unknown.is_empty() { "none".to_string() } else { unknown.join(", ") },
            stats.rows_from,
        ))
        .into());
    }
    let priors = SurveyPriors { fixed: Vec::new(), heights: heights.per_row(&anchor_ids)? };
    let survey = survey_anchors(&pairs, anchor_ids.len(), &priors).map_err(|e| match e {
        CoreError::InsufficientData(why) => {
            let rows: Vec<String> = anchor_ids.iter().enumerate().map(|(k, id)| format!("{k} = {id}")).collect();
            CoreError::InsufficientData(format!("{why} (anchor rows: {})", rows.join(", ")))
        }
        other => other,
    })?;
    let mut by_pair: BTreeMap<(usize, usize), Vec<f64>> = BTreeMap::new();
    for (p, r) in pairs.iter().zip(&survey.residuals_m) {
        by_pair.entry((p.i.min(p.j), p.i.max(p.j))).or_default().push(*r);
    }
    let pairs = by_pair
        .into_iter()
        .map(|((i, j), mut r)| {
            r.sort_by(f64::total_cmp);
            PairResiduals {
                i,
                j,
                count: r.len(),
                median_m: r[r.len() / 2],
                rms_m: (r.iter().map(|x| x * x).sum::<f64>() / r.len() as f64).sqrt(),
                max_abs_m: r.iter().fold(0.0, |m, x| m.max(x.abs())),
            }
        })
        .collect();
    Ok(LogSurvey { anchor_ids, survey, pairs, stats })
}

/// Reads the anchor-to-anchor ranges of the MCAP file `path` through `mapping`
/// ([`read_anchor_ranges_file`]) and surveys them ([`survey_ranges`]); `progress` gets the bytes
/// read so far.
///
/// # Errors
/// Those of [`read_anchor_ranges_file`] and [`survey_ranges`].
pub fn survey_log_file(path: &Path, mapping: &Mapping, heights: &Heights, progress: impl FnMut(u64)) -> Result<LogSurvey> {
    survey_ranges(read_anchor_ranges_file(path, mapping, progress)?, heights)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heights_by_row_or_by_id() {
        let ids: Vec<String> = ["A0", "A1", "A2"].iter().map(|s| s.to_string()).collect();
        let rows = Heights::parse("2.4, 2.6,nan").unwrap().per_row(&ids).unwrap();
        assert_eq!((rows[0], rows[1], rows[2].is_nan()), (2.4, 2.6, true));
        let by_id = Heights::parse("A2=0.5,A0=2.4").unwrap().per_row(&ids).unwrap();
        assert_eq!((by_id[0], by_id[1].is_nan(), by_id[2]), (2.4, true, 0.5));
        assert_eq!(Heights::parse(" ").unwrap(), Heights::Unknown);
        assert!(Heights::parse("").unwrap().per_row(&ids).unwrap().is_empty());
        let e = Heights::parse("2.4,2.6").unwrap().per_row(&ids).unwrap_err().to_string();
        assert!(e.contains("2 values") && e.contains("0 = A0, 1 = A1, 2 = A2"), "{e}");
        let e = Heights::parse("A9=1").unwrap().per_row(&ids).unwrap_err().to_string();
        assert!(e.contains("`A9`") && e.contains("not an anchor"), "{e}");
        for bad in ["2.4,x", "A0=2,2.5", "A0=1,A0=2", "A0="] {
            assert!(Heights::parse(bad).is_err(), "{bad}");
        }
    }
}
