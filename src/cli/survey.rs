//! `uwbimu-replay survey`: reads a log of anchor-to-anchor ranges through the mapping, surveys the
//! anchors ([`uwbimu_app::log_survey`]), prints what it read, the positions with their σ, the
//! survey's warnings and the residuals per pair, and writes the anchors as a file a replay takes.

use std::io::Write;
use std::path::Path;

use uwbimu_app::log_survey::{survey_log_file, Heights, LogSurvey};
use uwbimu_app::replay_config::ReplayConfig;
use uwbimu_io::files::anchors::write_anchor_file;
use uwbimu_io::IoResult as Result;

use super::args::SurveyArgs;
use super::report::{file_and_topics, stdout_error};

/// Runs the survey of `args`; returns the exit status (0).
///
/// # Errors
/// A replay file, heights or anchor ids that do not read; the errors of
/// [`survey_log_file`] (a corrupt file, no anchor-range topic, no usable range, too few pairs);
/// a failed write of the output or of stdout.
pub(super) fn run(args: &SurveyArgs) -> Result<u8> {
    let mut cfg = match &args.config {
        Some(p) => ReplayConfig::read(p)?,
        None => ReplayConfig::from_toml("", Path::new("."))?,
    };
    let m = &mut cfg.mapping.anchor_ranges;
    if !args.topics.is_empty() {
        m.topics.clone_from(&args.topics);
    }
    if !args.anchor_ids.is_empty() {
        m.anchor_ids = Some(args.anchor_ids.clone());
    }
    let mapping = cfg.mapping.validate()?;
    let heights = Heights::parse(args.heights.as_deref().unwrap_or(""))?;
    let s = survey_log_file(&args.file, &mapping, &heights, |_| {})?;
    if let Some(w) = s.stats.end.warning(&args.file.display().to_string()) {
        eprintln!("uwbimu-replay: warning: {w}");
    }
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    report(&mut out, &args.file, &s).map_err(stdout_error)?;
    if let Some(path) = &args.out {
        write_anchor_file(path, &s.anchor_ids, &s.survey.positions)?;
        writeln!(out, "wrote {} ({} anchors; replay with --anchors {0})", path.display(), s.anchor_ids.len())
            .map_err(stdout_error)?;
    }
    Ok(0)
}

/// What was read, the anchors with their σ, the warnings and the residuals per pair.
fn report(out: &mut impl Write, file: &Path, s: &LogSurvey) -> std::io::Result<()> {
    let st = &s.stats;
    file_and_topics(out, file, &st.topics)?;
    let unknown: Vec<&str> = st.unknown_ids.iter().map(String::as_str).collect();
    writeln!(
        out,
        "read: {} anchor-to-anchor ranges, {} used; dropped: {} not finite, negative or of one anchor, {} naming an unknown anchor{}",
        st.decoded,
        st.used,
        st.bad_value,
        st.unknown_anchor,
        if unknown.is_empty() { String::new() } else { format!(" ({})", unknown.join(", ")) }
    )?;
    let v = &s.survey;
    writeln!(out, "anchors: {} (rows from {}); frame: {}", s.anchor_ids.len(), st.rows_from, v.frame)?;
    writeln!(out, "robust σ of the ranges: {:.3} m", v.sigma_m)?;
    writeln!(out, "{:>4}  {:<16} {:>9} {:>9} {:>9} {:>7} {:>7} {:>7}", "row", "id", "x_m", "y_m", "z_m", "σx_m", "σy_m", "σz_m")?;
    for (k, (id, p)) in s.anchor_ids.iter().zip(&v.positions).enumerate() {
        let std = v.covariances[k].diagonal().map(|c| c.max(0.0).sqrt());
        writeln!(out, "{k:>4}  {id:<16} {:>9.4} {:>9.4} {:>9.4} {:>7.4} {:>7.4} {:>7.4}", p.x, p.y, p.z, std.x, std.y, std.z)?;
    }
    writeln!(out, "residuals per pair (surveyed − measured distance, m; negative: ranged too long, NLOS?):")?;
    writeln!(out, "{:>9}  {:<24} {:>5} {:>9} {:>8} {:>8}", "rows", "ids", "n", "median", "rms", "max|r|")?;
    for p in &s.pairs {
        let ids = format!("{} – {}", s.anchor_ids[p.i], s.anchor_ids[p.j]);
        writeln!(
            out,
            "{:>9}  {ids:<24} {:>5} {:>+9.4} {:>8.4} {:>8.4}",
            format!("{}–{}", p.i, p.j),
            p.count,
            p.median_m,
            p.rms_m,
            p.max_abs_m
        )?;
    }
    for w in &v.warnings {
        writeln!(out, "warning: {w}")?;
    }
    Ok(())
}
