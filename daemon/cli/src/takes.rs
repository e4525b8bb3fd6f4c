//! `frond take list|export|repair` (waiting for the motion crate's take codec).

use crate::args::Global;

pub(crate) fn list(_g: &Global, _json: bool) -> anyhow::Result<()> {
    anyhow::bail!("frond take list is not implemented yet")
}

pub(crate) fn export(_g: &Global, _name: &str, _fps: Option<f64>) -> anyhow::Result<()> {
    anyhow::bail!("frond take export is not implemented yet")
}

pub(crate) fn repair(_g: &Global, _name: &str) -> anyhow::Result<()> {
    anyhow::bail!("frond take repair is not implemented yet")
}
