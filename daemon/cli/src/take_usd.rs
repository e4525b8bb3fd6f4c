//! `frond take export NAME --usd -o FILE.usda|FILE.usdc`: a take as a USD (UsdSkel) layer
//! (`frond_formats::usd`): the rig's skinned mesh, skeleton and the take's animation at `--fps`
//! (default 30), on the take's rig (or `--rig`). The binary form is the same layer in USD's crate
//! format, written by openusd (vendored with a fix, `vendor/openusd`).

use std::path::Path;

use anyhow::anyhow;
use frond_formats::usd::{UsdTake, write_usda};

use crate::error::usage;
use crate::global::Global;
use crate::take_file::{TakeForFile, take_for_file};

/// What `--usd` was asked.
pub(crate) struct UsdExport<'a> {
    pub name: &'a str,
    pub output: &'a Path,
    pub fps: Option<f64>,
    pub rig: Option<&'a Path>,
    pub timecode_start: Option<&'a str>,
    pub force: bool,
}

/// Writes the USD layer.
pub(crate) fn export_usd(g: &Global, a: UsdExport<'_>) -> anyhow::Result<()> {
    let binary = match a.output.extension().and_then(|e| e.to_str()) {
        Some("usda") => false,
        Some("usdc") => true,
        Some("usd" | "usdz") => {
            return usage(format!(
                "{}: name the layer .usda (text) or .usdc (binary), so every tool knows which it is; \
                 a .usdz package is not written",
                a.output.display()
            ));
        }
        _ => {
            return usage(format!(
                "{}: a USD layer is named .usda (text) or .usdc (binary)",
                a.output.display()
            ));
        }
    };
    let fps = TakeForFile::fps(a.fps, "USD")?;
    let take = take_for_file(g, a.name, a.rig)?;
    let (scan, loaded) = (&take.scan, &take.rig);
    let model = frond_formats::rig_files::plant_model(loaded).map_err(|e| anyhow!("{e}"))?;
    let poses: Vec<_> = take.resampled(fps, a.force)?.iter().map(|p| p.joints_deg).collect();
    let joint_names: [String; 4] = std::array::from_fn(|j| loaded.rig.joints[j].name.clone());
    let timecode = crate::take_file::start_timecode(scan, fps, a.timecode_start)?;
    let h = scan.header.as_ref();
    let info = [
        ("timecode_start", timecode.map(|t| t.to_string()).unwrap_or_default()),
        ("timecode_rate", timecode.map(|t| t.rate.to_string()).unwrap_or_default()),
        ("take", a.name.to_string()),
        ("rig", loaded.rig.name.clone()),
        ("take_rig", h.map(|h| h.rig_name.clone()).unwrap_or_default()),
        ("calibration_id", h.map(|h| h.calibration_id.clone()).unwrap_or_default()),
        ("capture_rate_hz", h.map(|h| h.tick_rate_hz.to_string()).unwrap_or_default()),
        ("recorded_unix_s", h.map(|h| h.created_unix_s.to_string()).unwrap_or_default()),
    ];
    let take = UsdTake { name: &loaded.rig.name, joint_names: &joint_names, fps, info: &info };
    let mut out = String::new();
    write_usda(&take, &model, &poses, &mut out);
    let bytes = if binary { usdc_bytes(&out)? } else { out.into_bytes() };
    crate::calibrate::write_atomically_bytes(a.output, &bytes)?;
    frond_binmain::outln!("{}", a.output.display())?;
    Ok(())
}

/// The layer `text` (frond's own USDA) in USD's binary crate form: parsed by openusd, with
/// `elementSize` made the `int` USD declares it (openusd's text parser reads untyped metadata
/// numbers as `int64`, and usd-core then sees 1 influence per point instead of 4), and written by
/// openusd's crate writer.
fn usdc_bytes(text: &str) -> anyhow::Result<Vec<u8>> {
    use openusd::sdf::Value;
    let mut data = openusd::usda::parse(text).map_err(|e| anyhow!("converting the layer to USDC: {e}"))?;
    let paths: Vec<openusd::sdf::Path> = data.iter().map(|(p, _)| p.clone()).collect();
    for path in &paths {
        let Some(spec) = data.spec_mut(path) else { continue };
        for (name, value) in &mut spec.fields {
            if name == "elementSize"
                && let Value::Int64(n) = *value
            {
                *value = Value::Int(i32::try_from(n).map_err(|_| anyhow!("{path}: elementSize {n}"))?);
            }
        }
    }
    let mut out = std::io::Cursor::new(Vec::new());
    openusd::usdc::CrateWriter::write(&data, &mut out).map_err(|e| anyhow!("writing the USDC layer: {e}"))?;
    Ok(out.into_inner())
}
