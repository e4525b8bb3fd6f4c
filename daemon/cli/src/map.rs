//! `frond map`: offline hand-to-pose mapping through [`Mapper::process`], the code path of the
//! daemon's realtime loop.
//!
//! Malformed input lines are reported on stderr as `line N: <problem>` and skipped; every good
//! line is mapped and written, and the command then fails (status 1) if any line was bad, so a
//! script notices while a person still gets all the usable output. Blank lines are ignored.
//! After [`MAX_BAD_LINES`] malformed lines the input is not hand JSON Lines at all (a binary
//! file, the wrong file): `frond map` stops there and says so with the count, instead of
//! listing a line of complaint for every line of a large file.

use frond_motion::mapping::MAX_TIME_STEP_S;
use std::io::{self, BufRead, BufReader, Read, Write};
use std::path::Path;

use anyhow::{Context, bail};
use frond_formats::jsonl::{parse_hand_line, write_pose_line};
use frond_motion::{Calibration, Mapper};

use crate::control::{load_calibration, load_rig, parse_filter};

pub(crate) fn run(
    rig: &Path,
    calibration: Option<&Path>,
    filter: Option<&str>,
    input: Option<&Path>,
) -> anyhow::Result<()> {
    let (rig, _) = load_rig(rig)?;
    let calibration = match calibration {
        Some(path) => load_calibration(path)?.0,
        None => Calibration::neutral_for(&rig),
    };
    let filter = match filter {
        Some(spec) => parse_filter(spec)?,
        None => rig.filter,
    };
    let mut mapper = Mapper::new(rig.mapping(), calibration.params(), filter);
    let reader: Box<dyn Read> = match input {
        Some(path) => Box::new(
            std::fs::File::open(path).with_context(|| format!("cannot open input {}", path.display()))?,
        ),
        None => Box::new(io::stdin().lock()),
    };
    let mut out = frond_binmain::StdoutWriter::lock();
    let summary = map_stream(BufReader::new(reader), &mut out, &mut mapper, &mut io::stderr())?;
    out.flush()?;
    if summary.discontinuities > DISCONTINUITIES_LISTED {
        frond_binmain::errln!(
            "frond map: {} time discontinuities in all ({} listed above)",
            summary.discontinuities,
            DISCONTINUITIES_LISTED
        );
    }
    if let Some(line) = summary.stopped_at_line {
        bail!(
            "stopped at line {line}: {} malformed lines, the most frond map reads before it gives up \
             (is this hand JSON Lines, one {{\"t\":..,\"wrist\":[..],\"thumb\":[..]}} a line?); \
             the {} good lines before it were mapped",
            summary.bad,
            summary.good
        );
    }
    if summary.bad > 0 {
        bail!(
            "{} of {} input lines were malformed (listed above); the other {} were mapped",
            summary.bad,
            summary.bad + summary.good,
            summary.good
        );
    }
    Ok(())
}

/// What [`map_stream`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct MapSummary {
    /// Lines mapped.
    pub good: u64,
    /// Lines reported as malformed.
    pub bad: u64,
    /// Lines whose time broke the timeline (the filter was reset there, as live).
    pub discontinuities: u64,
    /// The line at which reading stopped after [`MAX_BAD_LINES`] malformed lines.
    pub stopped_at_line: Option<u64>,
}

/// Malformed lines [`map_stream`] reports before it stops reading.
pub(crate) const MAX_BAD_LINES: u64 = 100;

/// Time discontinuities reported line by line; past this, only counted.
const DISCONTINUITIES_LISTED: u64 = 10;

/// Maps every hand line of `input` to a pose line on `out`; reports bad lines on `errors`, and
/// stops reading at the [`MAX_BAD_LINES`]th (`stopped_at_line`). Fails only on I/O errors.
pub(crate) fn map_stream(
    mut input: impl BufRead,
    out: &mut impl Write,
    mapper: &mut Mapper,
    errors: &mut impl Write,
) -> anyhow::Result<MapSummary> {
    let mut summary = MapSummary::default();
    let mut raw = Vec::new();
    let mut line_out = String::with_capacity(256);
    let mut n = 0u64;
    loop {
        raw.clear();
        if input.read_until(b'\n', &mut raw).context("reading the hand input")? == 0 {
            break;
        }
        n += 1;
        let text = match std::str::from_utf8(&raw) {
            Ok(t) => t.trim(),
            Err(e) => {
                writeln!(errors, "line {n}: not UTF-8 text ({e})")?;
                summary.bad += 1;
                if summary.bad >= MAX_BAD_LINES {
                    summary.stopped_at_line = Some(n);
                    break;
                }
                continue;
            }
        };
        if text.is_empty() {
            continue;
        }
        match parse_hand_line(text) {
            Ok(sample) => {
                let (_, pose) = mapper.process(&sample);
                if mapper.discontinuity() {
                    summary.discontinuities += 1;
                    if summary.discontinuities <= DISCONTINUITIES_LISTED {
                        writeln!(
                            errors,
                            "line {n}: t = {} does not follow the previous line's time (it jumps over {MAX_TIME_STEP_S} s, goes back or repeats): the filter starts afresh here",
                            sample.t
                        )?;
                    }
                }
                line_out.clear();
                write_pose_line(&pose, None, &mut line_out);
                line_out.push('\n');
                out.write_all(line_out.as_bytes())?;
                summary.good += 1;
            }
            Err(e) => {
                writeln!(errors, "line {n}: {e}")?;
                summary.bad += 1;
                if summary.bad >= MAX_BAD_LINES {
                    summary.stopped_at_line = Some(n);
                    break;
                }
            }
        }
    }
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use frond_motion::{CalibrationParams, FilterSpec, MappingParams};

    use super::*;

    fn mapper() -> Mapper {
        Mapper::new(
            MappingParams::default(),
            CalibrationParams::neutral([60.0, 70.0, 60.0]),
            FilterSpec::None,
        )
    }

    #[test]
    fn maps_good_lines_and_reports_bad_ones_by_number() {
        let input = concat!(
            "{\"t\":0.5,\"wrist\":[20,-10,30],\"thumb\":[30,35,15]}\n",
            "\n",
            "{\"t\":0.6,\"wrist\":[1,2],\"thumb\":[0,0,0]}\n",
            "not json\n",
            "{\"t\":0.7,\"wrist\":[0,0,0],\"thumb\":[0,0,0]}",
        );
        let mut out = Vec::new();
        let mut err = Vec::new();
        let s = map_stream(input.as_bytes(), &mut out, &mut mapper(), &mut err).unwrap();
        assert_eq!(s, MapSummary { good: 2, bad: 2, discontinuities: 0, stopped_at_line: None });
        let out = String::from_utf8(out).unwrap();
        // Unit scales, tau 2, G/G_R = 0.5, 0.5, 0.25 (see the motion crate's hand computation).
        assert_eq!(
            out,
            "{\"t\":0.5,\"joints\":[[20.0,-10.0,0.0],[10.0,-5.0,0.0],[10.0,-5.0,30.0],[5.0,-2.5,30.0]]}\n\
             {\"t\":0.7,\"joints\":[[0.0,0.0,0.0],[0.0,0.0,0.0],[0.0,0.0,0.0],[0.0,0.0,0.0]]}\n"
        );
        let err = String::from_utf8(err).unwrap();
        let lines: Vec<&str> = err.lines().collect();
        assert_eq!(lines.len(), 2, "{err}");
        assert!(lines[0].starts_with("line 3: ") && lines[0].contains("wrist"), "{err}");
        assert!(lines[1].starts_with("line 4: not JSON"), "{err}");
    }

    #[test]
    fn invalid_utf8_is_a_bad_line_not_a_failure() {
        let mut input = b"\xff\xfe\n".to_vec();
        input.extend_from_slice(b"{\"t\":0,\"wrist\":[0,0,0],\"thumb\":[0,0,0]}\n");
        let (mut out, mut err) = (Vec::new(), Vec::new());
        let s = map_stream(&input[..], &mut out, &mut mapper(), &mut err).unwrap();
        assert_eq!(s, MapSummary { good: 1, bad: 1, discontinuities: 0, stopped_at_line: None });
        assert!(String::from_utf8(err).unwrap().starts_with("line 1: not UTF-8"));
    }

    #[test]
    fn reading_stops_at_the_hundredth_bad_line() {
        // 3 good lines, then 250 lines of garbage with a good line after them: lines 4..=103
        // are the first 100 bad ones, and nothing after line 103 is read.
        let good = "{\"t\":0,\"wrist\":[0,0,0],\"thumb\":[0,0,0]}\n";
        let mut input = good.repeat(3);
        input.push_str(&"garbage\n".repeat(250));
        input.push_str(good);
        let (mut out, mut err) = (Vec::new(), Vec::new());
        let s = map_stream(input.as_bytes(), &mut out, &mut mapper(), &mut err).unwrap();
        assert_eq!(s, MapSummary { good: 3, bad: 100, discontinuities: 2, stopped_at_line: Some(103) });
        assert_eq!(String::from_utf8(out).unwrap().lines().count(), 3);
        let err = String::from_utf8(err).unwrap();
        let bad: Vec<&str> = err.lines().filter(|l| l.contains("not JSON")).collect();
        assert_eq!(bad.len(), 100, "{err}");
        assert!(bad[99].starts_with("line 103: "), "{err}");
    }
}
