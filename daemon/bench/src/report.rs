//! The bench report: sections of measurements, each a measured value beside the baseline measured
//! in the same run, their ratio, and the target it is held to (if any).

use serde::Serialize;
use serde::ser::{SerializeMap, Serializer};
use serde_json::Value;

/// Version of the JSON layout.
pub const SCHEMA: u32 = 1;

/// What a target bounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Bound {
    /// `ratio <= limit`.
    MaxRatio,
    /// `measured <= limit` (in the measurement's unit).
    MaxMeasured,
}

/// A target and whether the measurement meets it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Target {
    /// The target as the issue states it.
    pub text: String,
    /// What is bounded.
    pub bound: Bound,
    /// The bound.
    pub limit: f64,
    /// Whether it holds in this run.
    pub holds: bool,
}

/// One measurement with its same-run baseline.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Measurement {
    /// Name, unique within the section (`lateness_p99_1000hz`).
    pub name: String,
    /// Unit of `measured` and `baseline` (`us`, `ns`, `hz`, `fraction_of_core`, `bytes`, ...).
    pub unit: String,
    /// The measured value.
    pub measured: f64,
    /// What the baseline is (measured in the same run, never a constant).
    pub baseline_name: String,
    /// The baseline's value.
    pub baseline: f64,
    /// `measured / baseline`; `null` when the baseline is 0.
    pub ratio: Option<f64>,
    /// The target, if one applies.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub target: Option<Target>,
}

impl Measurement {
    /// A measurement; the ratio is computed here from the two values.
    pub fn new(
        name: impl Into<String>,
        unit: impl Into<String>,
        measured: f64,
        baseline_name: impl Into<String>,
        baseline: f64,
    ) -> Self {
        Measurement {
            name: name.into(),
            unit: unit.into(),
            measured,
            baseline_name: baseline_name.into(),
            baseline,
            ratio: ratio(measured, baseline),
            target: None,
        }
    }

    /// Adds a target: `bound` of this measurement at most `limit`.
    pub fn with_target(mut self, text: impl Into<String>, bound: Bound, limit: f64) -> Self {
        let value = match bound {
            Bound::MaxRatio => self.ratio,
            Bound::MaxMeasured => Some(self.measured),
        };
        let holds = value.is_some_and(|v| v.is_finite() && v <= limit);
        self.target = Some(Target { text: text.into(), bound, limit, holds });
        self
    }
}

/// `measured / baseline`, or `None` when that is not a finite number.
pub fn ratio(measured: f64, baseline: f64) -> Option<f64> {
    let r = measured / baseline;
    (baseline != 0.0 && r.is_finite()).then_some(r)
}

/// Whether a section (or part) could be measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Status {
    /// Measured.
    #[serde(rename = "ok")]
    Ok,
    /// The component does not exist (yet) or cannot run here; `reason` says why.
    #[serde(rename = "not available")]
    NotAvailable,
    /// The measurement failed; `reason` says how.
    #[serde(rename = "error")]
    Error,
}

/// One section of the report (or one part of a section).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Section {
    /// Key of the section.
    #[serde(skip)]
    pub name: String,
    /// What it measures.
    pub title: String,
    /// Outcome.
    pub status: Status,
    /// Why it is not `ok`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// Wall time the section took, seconds.
    pub seconds: f64,
    /// The measurements.
    pub measurements: Vec<Measurement>,
    /// Raw figures behind the measurements (percentiles, counts, settings).
    #[serde(skip_serializing_if = "Value::is_null")]
    pub details: Value,
    /// Sub-sections (section 6: one per component).
    #[serde(skip_serializing_if = "Vec::is_empty", serialize_with = "ordered_map")]
    pub parts: Vec<Section>,
}

impl Section {
    /// A measured section.
    pub fn ok(name: &str, title: &str, measurements: Vec<Measurement>, details: Value) -> Self {
        Section {
            name: name.into(),
            title: title.into(),
            status: Status::Ok,
            reason: None,
            seconds: 0.0,
            measurements,
            details,
            parts: Vec::new(),
        }
    }

    /// A section that could not be measured.
    pub fn unavailable(name: &str, title: &str, status: Status, reason: impl Into<String>) -> Self {
        Section {
            name: name.into(),
            title: title.into(),
            status,
            reason: Some(reason.into()),
            seconds: 0.0,
            measurements: Vec::new(),
            details: Value::Null,
            parts: Vec::new(),
        }
    }
}

/// The machine the run was on.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Machine {
    /// Online CPUs.
    pub nproc: usize,
    /// `model name` from /proc/cpuinfo.
    pub cpu_model: String,
    /// `uname -r`.
    pub kernel: String,
    /// 1-minute load average at the start (other work on the machine).
    pub load_avg_1m: f64,
    /// Realtime scheduling the bench loops ran with.
    pub realtime: String,
}

/// One row of the targets summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TargetRow {
    /// Section key.
    pub section: String,
    /// Measurement name.
    pub measurement: String,
    /// The target.
    pub text: String,
    /// Whether it holds.
    pub holds: bool,
}

/// The whole report (`frond bench --json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// [`SCHEMA`].
    pub schema: u32,
    /// frond version.
    pub frond_version: String,
    /// Quick mode (CI): short measurements.
    pub quick: bool,
    /// The machine.
    pub machine: Machine,
    /// Sections by key, in order.
    #[serde(serialize_with = "ordered_map")]
    pub sections: Vec<Section>,
    /// Every target and whether it holds.
    pub targets: Vec<TargetRow>,
}

impl Report {
    /// Collects the targets of every section and part.
    pub fn collect_targets(&mut self) {
        fn walk(prefix: &str, s: &Section, out: &mut Vec<TargetRow>) {
            let key = if prefix.is_empty() { s.name.clone() } else { format!("{prefix}.{}", s.name) };
            for m in &s.measurements {
                if let Some(t) = &m.target {
                    out.push(TargetRow {
                        section: key.clone(),
                        measurement: m.name.clone(),
                        text: t.text.clone(),
                        holds: t.holds,
                    });
                }
            }
            for p in &s.parts {
                walk(&key, p, out);
            }
        }
        let mut rows = Vec::new();
        for s in &self.sections {
            walk("", s, &mut rows);
        }
        self.targets = rows;
    }

    /// A readable table of every section, measurement and target.
    pub fn to_table(&self) -> String {
        use std::fmt::Write;
        let mut out = String::new();
        let m = &self.machine;
        let _ = writeln!(
            out,
            "frond bench {} ({} mode) on {} x {} ({}), load {:.2}, {}",
            self.frond_version,
            if self.quick { "quick" } else { "full" },
            m.nproc,
            m.cpu_model,
            m.kernel,
            m.load_avg_1m,
            m.realtime
        );
        fn section(out: &mut String, prefix: &str, s: &Section) {
            let key = if prefix.is_empty() { s.name.clone() } else { format!("{prefix}.{}", s.name) };
            let _ = writeln!(out, "\n[{key}] {} ({:.1} s)", s.title, s.seconds);
            if let Some(r) = &s.reason {
                let status = match s.status {
                    Status::Ok => "ok",
                    Status::NotAvailable => "not available",
                    Status::Error => "error",
                };
                let _ = writeln!(out, "  {status}: {r}");
            }
            for m in &s.measurements {
                let ratio = m.ratio.map_or("-".to_string(), |r| format!("{r:.2}x"));
                let target = m.target.as_ref().map_or(String::new(), |t| {
                    format!("  [{}: {}]", if t.holds { "HOLDS" } else { "MISSED" }, t.text)
                });
                let _ = writeln!(
                    out,
                    "  {:<34} {:>12} {:<16} vs {:>12} ({}) = {:>8}{}",
                    m.name,
                    fmt_num(m.measured),
                    m.unit,
                    fmt_num(m.baseline),
                    m.baseline_name,
                    ratio,
                    target
                );
            }
            for p in &s.parts {
                section(out, &key, p);
            }
        }
        for s in &self.sections {
            section(&mut out, "", s);
        }
        let held = self.targets.iter().filter(|t| t.holds).count();
        let _ = writeln!(out, "\ntargets: {held} of {} hold", self.targets.len());
        for t in &self.targets {
            let _ = writeln!(
                out,
                "  {:<6} {}.{}: {}",
                if t.holds { "HOLDS" } else { "MISSED" },
                t.section,
                t.measurement,
                t.text
            );
        }
        out
    }
}

fn fmt_num(v: f64) -> String {
    if v == 0.0 || (v.abs() >= 0.01 && v.abs() < 1e7) { format!("{v:.2}") } else { format!("{v:.3e}") }
}

fn ordered_map<S: Serializer>(sections: &[Section], s: S) -> Result<S::Ok, S::Error> {
    let mut map = s.serialize_map(Some(sections.len()))?;
    for section in sections {
        map.serialize_entry(&section.name, section)?;
    }
    map.end()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ratio_and_targets_come_from_the_values() {
        let m = Measurement::new("x", "us", 30.0, "base", 20.0).with_target("<= 1.5x", Bound::MaxRatio, 1.5);
        assert_eq!(m.ratio, Some(1.5));
        assert!(m.target.unwrap().holds);
        let m = Measurement::new("x", "us", 31.0, "base", 20.0).with_target("<= 1.5x", Bound::MaxRatio, 1.5);
        assert!(!m.target.unwrap().holds);
        let m =
            Measurement::new("x", "ns", 900.0, "base", 0.0).with_target("< 1 us", Bound::MaxMeasured, 1000.0);
        assert_eq!(m.ratio, None);
        assert!(m.target.unwrap().holds);
        let m = Measurement::new("x", "us", 1.0, "base", 0.0).with_target("r", Bound::MaxRatio, 1.5);
        assert!(!m.target.unwrap().holds, "no ratio, no claim");
    }

    #[test]
    fn sections_serialize_as_an_ordered_object() {
        let mut r = Report {
            schema: SCHEMA,
            frond_version: "0".into(),
            quick: true,
            machine: Machine {
                nproc: 1,
                cpu_model: "c".into(),
                kernel: "k".into(),
                load_avg_1m: 0.0,
                realtime: "normal".into(),
            },
            sections: vec![
                Section::ok(
                    "zeta",
                    "z",
                    vec![Measurement::new("a", "us", 2.0, "b", 1.0).with_target("t", Bound::MaxRatio, 3.0)],
                    Value::Null,
                ),
                Section::unavailable("alpha", "a", Status::NotAvailable, "not yet"),
            ],
            targets: vec![],
        };
        r.collect_targets();
        let text = serde_json::to_string(&r).unwrap();
        assert!(text.find("\"zeta\"").unwrap() < text.find("\"alpha\"").unwrap(), "{text}");
        let v: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["sections"]["alpha"]["status"], "not available");
        assert_eq!(v["sections"]["zeta"]["measurements"][0]["ratio"], 2.0);
        assert_eq!(v["targets"][0]["section"], "zeta");
        assert!(r.to_table().contains("HOLDS"));
    }
}
