//! Semantic checks of a parsed job: every bad value named by its field path
//! (`pipeline.tile`, `pipelines[1].name`, `lights[0]`), so the user knows
//! what to edit.

use super::schema::{Job, JOB_VERSION};
use crate::{Error, Result};
use std::path::Path;

impl Job {
    pub(super) fn validate(&self, file: &Path) -> Result<()> {
        let bad = |field: &str, message: String| Error::Job {
            file: file.to_path_buf(),
            location: field.to_string(),
            message,
        };
        if self.version != JOB_VERSION {
            return Err(bad(
                "version",
                format!(
                    "unsupported job version {} (this build reads {JOB_VERSION})",
                    self.version
                ),
            ));
        }
        let (w, h) = self.resolution;
        if w == 0 || h == 0 || w > 16384 || h > 16384 {
            return Err(bad(
                "resolution",
                format!("{w}×{h} must be between 1×1 and 16384×16384"),
            ));
        }
        if let Some(g) = self.ground {
            if g.size <= 0.0 || !g.size.is_finite() || !g.y.is_finite() {
                return Err(bad(
                    "ground",
                    "size must be positive and finite, y finite".into(),
                ));
            }
        }
        if self.frames == Some(0) {
            return Err(bad("frames", "must be at least 1".into()));
        }
        if self.keyframe == Some(0) {
            return Err(bad("keyframe", "must be at least 1".into()));
        }
        if self.outputs.image_every == 0 {
            return Err(bad("outputs.image_every", "must be at least 1".into()));
        }
        let variants = std::iter::once(("pipeline".to_string(), &self.pipeline)).chain(
            self.pipelines
                .iter()
                .enumerate()
                .map(|(i, p)| (format!("pipelines[{i}].pipeline"), &p.pipeline)),
        );
        for (at, p) in variants {
            if let Err(e) = p.validate() {
                return Err(bad(&format!("{at}.{}", e.field), e.message));
            }
        }
        let mut names = std::collections::HashSet::new();
        for (i, p) in self.pipelines.iter().enumerate() {
            if p.name.is_empty() || !names.insert(p.name.as_str()) {
                return Err(bad(
                    &format!("pipelines[{i}].name"),
                    format!("{:?} must be non-empty and unique", p.name),
                ));
            }
        }
        for (i, l) in self.lights.iter().enumerate() {
            if let Ok(Some(light)) = l.to_light_static() {
                light
                    .validate()
                    .map_err(|e| bad(&format!("lights[{i}]"), e.to_string()))?;
            }
        }
        Ok(())
    }
}
