//! RON job files: which scene, views, lights, outputs and pipeline options a
//! batch run uses.
//!
//! The schema grows without breaking old jobs: `version: 1`, and every field
//! but `scene` has a default. Unknown fields and bad values are errors with
//! line and column (or the field's path).

use crate::pipeline::PipelineOptions;
use crate::{Error, Result};
use glam::DVec3;
use scene::procedural::city::CityParams;
use scene::LookAt;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The job schema version this build reads.
pub const JOB_VERSION: u32 = 1;

/// A batch job.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Job {
    /// Schema version; must be [`JOB_VERSION`].
    #[serde(default = "default_version")]
    pub version: u32,
    /// The scene to load or generate.
    pub scene: SceneSpec,
    /// An optional ground quad added under the scene.
    #[serde(default)]
    pub ground: Option<Ground>,
    /// Viewport `(width, height)` in pixels; default 800×600.
    #[serde(default = "default_resolution")]
    pub resolution: (u32, u32),
    /// The view(s): a camera or camera path.
    #[serde(default)]
    pub camera: CameraSpec,
    /// Number of frames; default: the camera's sequence length, else 1.
    #[serde(default)]
    pub frames: Option<u32>,
    /// Reset all coherent state (culling histories, caches) every this many
    /// frames, at job frames 0, K, 2K, … ([`crate::Pipeline::reset_history`]):
    /// a job split into shards on multiples of K then equals the single run
    /// in every column but times. Default: never (history runs through).
    #[serde(default)]
    pub keyframe: Option<u32>,
    /// Lights; each frame is computed once per light. Default: the scene's
    /// named lights, else one point light above the scene.
    #[serde(default)]
    pub lights: Vec<LightSpec>,
    /// Which files to write.
    #[serde(default)]
    pub outputs: Outputs,
    /// Pipeline options.
    #[serde(default)]
    pub pipeline: PipelineOptions,
    /// Variants `shadowcull compare` runs on the same frames (empty: brute
    /// force, depth bounds, and scissor with depth bounds, each otherwise
    /// like `pipeline`).
    #[serde(default)]
    pub pipelines: Vec<NamedPipeline>,
}

fn default_version() -> u32 {
    JOB_VERSION
}

fn default_resolution() -> (u32, u32) {
    (800, 600)
}

/// Where the scene comes from. Relative paths are relative to the job file.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum SceneSpec {
    /// A glTF 2.0 file (`.gltf` or `.glb`).
    Gltf(PathBuf),
    /// An OBJ file, or a directory of OBJ files loaded in name order.
    Obj(PathBuf),
    /// A box-city benchmark file (`citysc 1`).
    BoxCity(PathBuf),
    /// The procedural city with parameters (`City(())` for the defaults).
    City(CityParams),
    /// Several scenes combined into one.
    Group(Vec<SceneSpec>),
    /// Every object of a scene baked into one object (world-space vertices,
    /// one mesh at the identity): a level exported as a single draw, where
    /// object culling has nothing to remove (`Merged(City(()))`).
    Merged(Box<SceneSpec>),
}

/// A ground quad: a square of side `size` centred under the scene bounds, at height `y`, facing up.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ground {
    /// Edge length.
    pub size: f32,
    /// Height of the quad.
    pub y: f32,
}

/// The view of each frame.
#[derive(Clone, Debug, PartialEq, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub enum CameraSpec {
    /// A fixed pose.
    Fixed(LookAt),
    /// One pose per frame, in order (frame i uses pose i).
    Sequence(Vec<LookAt>),
    /// A camera the scene names (box city: `street`, `bird`).
    Named(String),
    /// A camera path the scene names (`street`, `bird`).
    Path(String),
    /// Keyframes `(frame, pose)`, linearly interpolated.
    Keyframes(Vec<(f64, LookAt)>),
    /// Default: the scene's `street` path if it has one, else a view of the
    /// whole scene bounds from the side.
    #[default]
    Auto,
}

/// A light of the job.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum LightSpec {
    /// Point light; `range` limits it.
    Point {
        /// Position.
        position: DVec3,
        /// Optional range.
        #[serde(default)]
        range: Option<f64>,
    },
    /// Spot light; `apex_deg` is the full cone angle in degrees.
    Spot {
        /// Position.
        position: DVec3,
        /// Axis direction.
        direction: DVec3,
        /// Full apex angle in degrees, (0, 180).
        apex_deg: f64,
        /// Optional range.
        #[serde(default)]
        range: Option<f64>,
    },
    /// Directional light travelling along `direction`.
    Directional(DVec3),
    /// The sun at `elevation_deg` above the horizon and `azimuth_deg`
    /// counter-clockwise from +x seen from above (toward −z).
    Sun {
        /// Elevation in degrees.
        elevation_deg: f64,
        /// Azimuth in degrees.
        azimuth_deg: f64,
    },
    /// A point light above the centre of the scene bounds at
    /// `min.y + factor · height` (height = bounds' y extent).
    AboveScene(f64),
    /// A light the scene names (box city: `light`).
    Named(String),
}

/// Files a run writes besides `stats.csv` and `summary.json`.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Outputs {
    /// `frames/<frame>_<light>_mask.png`: the four-class reference mask.
    pub masks: bool,
    /// `frames/<frame>_<light>_shaded.png`: a shaded image of the frame.
    pub shaded: bool,
    /// `frames/<frame>_<light>_tiles.png`: the hierarchical stencil's tile
    /// classification (lit white, shadow blue, boundary orange, background
    /// black; [Aila04 Fig. 1]); only with `pipeline.stencil: h`.
    pub tile_image: bool,
    /// Write images only for every n-th frame (1 = all).
    pub image_every: u32,
}

impl Default for Outputs {
    fn default() -> Self {
        Outputs {
            masks: false,
            shaded: false,
            tile_image: false,
            image_every: 1,
        }
    }
}

/// One variant of `shadowcull compare`: a name and its pipeline options.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NamedPipeline {
    /// Row name in `compare.csv` and label in `compare.svg`.
    pub name: String,
    /// The options (defaults as in the job's `pipeline`).
    #[serde(default)]
    pub pipeline: PipelineOptions,
}

impl Job {
    /// Parses a job from RON text; `file` names it in errors.
    ///
    /// # Errors
    /// [`Error::Job`] with line and column for syntax errors, unknown fields
    /// and bad values.
    pub fn from_ron(text: &str, file: &Path) -> Result<Job> {
        // Editors on Windows may start the file with a byte-order mark.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let job: Job = ron::Options::default()
            .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
            .from_str(text)
            .map_err(|e| Error::Job {
                file: file.to_path_buf(),
                location: format!("{}:{}", e.span.start.line, e.span.start.col),
                message: explain(text, e.span.start.line, e.span.start.col, &e.code)
                    .unwrap_or_else(|| e.code.to_string()),
            })?;
        job.validate(file)?;
        Ok(job)
    }

    /// Reads and parses a job file: a regular file within the input size
    /// limit ([`scene::load::read_input`]), UTF-8 with or without a
    /// byte-order mark.
    ///
    /// # Errors
    /// [`Error::Io`], or [`Error::Job`] (with `line:column` for invalid UTF-8).
    pub fn from_file(path: &Path) -> Result<Job> {
        let bytes = scene::load::read_input(path).map_err(crate::error::io_err(path))?;
        let text = String::from_utf8(bytes).map_err(|e| {
            let valid = &e.as_bytes()[..e.utf8_error().valid_up_to()];
            let line = valid.iter().filter(|&&b| b == b'\n').count() + 1;
            let line_start = valid.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
            let col = String::from_utf8_lossy(&valid[line_start..])
                .chars()
                .count()
                + 1;
            Error::Job {
                file: path.to_path_buf(),
                location: format!("{line}:{col}"),
                message: format!(
                    "invalid UTF-8 (byte 0x{:02x}): a job file is UTF-8 text",
                    e.as_bytes()[valid.len()]
                ),
            }
        })?;
        Job::from_ron(&text, path)
    }

    /// The number of frames the job asks for.
    pub fn frame_count(&self) -> u32 {
        self.frames.unwrap_or(match &self.camera {
            CameraSpec::Sequence(v) => v.len().max(1) as u32,
            _ => 1,
        })
    }
}

/// The bundled default job: the procedural city's `street` path at 800×600,
/// a point light 1.5× the city height above its centre and a sun at 35°
/// elevation, azimuth 30° from +x; conservative CHC++ culling (PSR, PSC) and
/// the hierarchical stencil; masks and shaded images written.
pub fn default_job() -> Job {
    Job {
        version: JOB_VERSION,
        scene: SceneSpec::City(CityParams::default()),
        ground: None,
        resolution: (800, 600),
        camera: CameraSpec::Path("street".into()),
        frames: Some(8),
        keyframe: None,
        lights: vec![
            LightSpec::AboveScene(1.5),
            LightSpec::Sun {
                elevation_deg: 35.0,
                azimuth_deg: 30.0,
            },
        ],
        outputs: Outputs {
            masks: true,
            shaded: true,
            tile_image: true,
            image_every: 1,
        },
        pipeline: PipelineOptions {
            stencil: crate::pipeline::StencilBackend::H,
            culling: crate::pipeline::CullingSpec::Chcpp,
            ..PipelineOptions::default()
        },
        pipelines: Vec::new(),
    }
}

/// A clearer message than the parser's where it is known to mislead: a
/// fraction where a whole number belongs. ron stops after the `2` of
/// `frames: 2.5` and reports "Expected comma" there (`stopped_after`), or
/// rejects `2e3` at its start with "Invalid digit" (`at_start`). `line` and
/// `col` are the parser's 1-based position. Anything else keeps ron's text.
fn explain(text: &str, line: usize, col: usize, code: &ron::Error) -> Option<String> {
    let stopped_after = matches!(code, ron::Error::ExpectedComma);
    let at_start = matches!(
        code,
        ron::Error::InvalidIntegerDigit { .. } | ron::Error::ExpectedInteger
    );
    if !(stopped_after || at_start) {
        return None;
    }
    let line_start = match line {
        0 => return None,
        1 => 0,
        _ => text.match_indices('\n').nth(line - 2)?.0 + 1,
    };
    let at = line_start
        + text[line_start..]
            .char_indices()
            .nth(col.checked_sub(1)?)?
            .0;
    let start = if stopped_after {
        // Digits just before, then `.5` or `e3`.
        let rest = &text[at..];
        let fraction = rest.starts_with('.') && rest[1..].starts_with(|c: char| c.is_ascii_digit());
        let digits = text[..at]
            .trim_end_matches(|c: char| c.is_ascii_digit())
            .len();
        if !(fraction || rest.starts_with(['e', 'E'])) || digits == at {
            return None;
        }
        text[..digits]
            .strip_suffix(['-', '+'])
            .map_or(digits, str::len)
    } else {
        at
    };
    // The number must stand alone: `0x1.5` is not a fraction of `1`.
    let delimited = text[..start]
        .chars()
        .next_back()
        .is_none_or(|c| c.is_whitespace() || matches!(c, '(' | '[' | ',' | ':'));
    let number: String = text[start..]
        .chars()
        .take_while(|&c| c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '+'))
        .collect();
    if !(delimited && number.contains(['.', 'e', 'E']) && number.parse::<f64>().is_ok()) {
        return None;
    }
    let field = text[..start]
        .trim_end()
        .strip_suffix(':')
        .and_then(|b| {
            b.trim_end()
                .rsplit(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .next()
        })
        .filter(|f| !f.is_empty());
    Some(match field {
        Some(f) => format!("`{f}` must be a whole number, not {number}"),
        None => format!("expected a whole number, not {number}"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::{CoverageSpec, CullingSpec, StencilBackend};
    use shadowgen::MethodChoice;

    fn parse(s: &str) -> Result<Job> {
        Job::from_ron(s, Path::new("test.ron"))
    }

    #[test]
    fn minimal_job_gets_defaults() {
        let j = parse("(scene: Obj(\"a.obj\"))").unwrap();
        assert_eq!(j.version, 1);
        assert_eq!(j.resolution, (800, 600));
        assert_eq!(j.camera, CameraSpec::Auto);
        assert_eq!(j.pipeline.reference_every, 1);
        assert_eq!(j.frame_count(), 1);
    }

    /// The culling fields as the issue spells them, and bad values naming
    /// their field.
    #[test]
    fn culling_fields_parse_and_bad_values_name_their_field() {
        let j = parse(
            r#"(version: 1, scene: City(()), pipeline: (culling: chcpp, coverage: conservative,
                light_resolution: 1024, query_threshold: 0,
                chcpp: (batch: 50, revisit: 5, seed: 1)))"#,
        )
        .unwrap();
        let p = &j.pipeline;
        assert_eq!(
            (p.culling, p.coverage),
            (CullingSpec::Chcpp, CoverageSpec::Conservative)
        );
        assert_eq!(
            p.culling(),
            visibility::Culling::ChcPlusPlus(visibility::ChcppOptions::default())
        );
        let j = parse(
            r#"(version: 1, scene: City(()), pipeline: (coverage: point, chcpp: (seed: 9)))"#,
        )
        .unwrap();
        assert_eq!(j.pipeline.coverage, CoverageSpec::Point);
        assert_eq!((j.pipeline.chcpp.batch, j.pipeline.chcpp.seed), (50, 9));
        let j = parse(
            r#"(version: 1, scene: City(()), pipeline: (culling: auto,
                auto: (probe: 4, min_objects: 2, eye_node: 0.5)))"#,
        )
        .unwrap();
        let a = j.pipeline.auto;
        assert_eq!(j.pipeline.culling, CullingSpec::Auto);
        assert_eq!((a.probe, a.min_objects, a.eye_node), (4, 2, 0.5));
        assert_eq!(a.light_node, crate::AutoSpec::default().light_node);
        let j = parse(
            r#"(version: 1, scene: City(()), pipeline: (stencil: auto,
                auto: (stencil: (h_tile: 3.5))))"#,
        )
        .unwrap();
        let t = j.pipeline.auto.stencil;
        assert_eq!(j.pipeline.stencil, crate::StencilBackend::Auto);
        assert_eq!(t.h_tile, 3.5);
        assert_eq!(t.db_fragment, crate::StencilCosts::default().db_fragment);
        for (text, field) in [
            ("chcpp: (batch: 0)", "pipeline.chcpp"),
            ("light_resolution: 4", "pipeline.light_resolution"),
            ("slices: 0", "pipeline.slices"),
            ("slices: 65", "pipeline.slices"),
            ("auto: (probe: 0)", "pipeline.auto.probe"),
            ("auto: (margin: 0.5)", "pipeline.auto.margin"),
            ("auto: (eye_tile: -1.0)", "pipeline.auto"),
            ("auto: (stencil: (db_pixel: inf))", "pipeline.auto.stencil"),
        ] {
            let e = parse(&format!(
                "(version: 1, scene: City(()), pipeline: ({text}))"
            ))
            .unwrap_err()
            .to_string();
            assert!(e.contains(field), "{e}");
        }
        for text in [
            "culling: chcp",
            "coverage: exact",
            "chcpp: (batches: 5)",
            "auto: (probes: 5)",
            "auto: (stencil: (h_tiles: 5))",
        ] {
            let e = parse(&format!(
                "(version: 1, scene: City(()), pipeline: ({text}))"
            ));
            assert!(e.is_err(), "{text}");
        }
    }

    /// Every struct of the schema rejects a misspelled field: the test walks
    /// jobs that use every struct and struct variant, inserts `zz_typo: 1`
    /// at each struct opening `(name:` in turn, and expects an error naming it.
    #[test]
    fn a_misspelled_field_is_rejected_at_every_level() {
        let pose = "(eye: (0.0, 1.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 60.0, near: 0.1)";
        let jobs = [
            format!(
                r#"(version: 1,
                scene: Group([City((seed: 3, blocks_x: 2)), Obj("a.obj")]),
                ground: Some((size: 100.0, y: 0.0)),
                resolution: (320, 240),
                camera: Fixed({pose}),
                frames: 2,
                lights: [
                    Point(position: (0.0, 9.0, 0.0), range: Some(20.0)),
                    Spot(position: (0.0, 9.0, 0.0), direction: (0.0, -1.0, 0.0), apex_deg: 40.0),
                    Sun(elevation_deg: 35.0, azimuth_deg: 30.0),
                ],
                outputs: (masks: true, image_every: 2),
                pipeline: (stencil: h, culling: chcpp, chcpp: (batch: 10), reference: (depth_error: 1e-6)),
                pipelines: [(name: "a", pipeline: (tile: 4, chcpp: (seed: 2)))])"#
            ),
            format!(r#"(scene: City(()), camera: Sequence([{pose}, {pose}]))"#),
            format!(r#"(scene: City(()), camera: Keyframes([(0.0, {pose}), (9.0, {pose})]))"#),
        ];
        let mut levels = std::collections::BTreeSet::new();
        for job in &jobs {
            parse(job).unwrap();
            let b = job.as_bytes();
            for open in (0..b.len()).filter(|&i| b[i] == b'(') {
                let rest = job[open + 1..].trim_start();
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_ascii_lowercase() || *c == '_')
                    .collect();
                if name.is_empty() || !rest[name.len()..].trim_start().starts_with(':') {
                    continue; // a tuple, a list or a variant's value, not a struct
                }
                levels.insert(name.clone());
                let typo = format!("{}zz_typo: 1, {}", &job[..=open], &job[open + 1..]);
                let e = parse(&typo)
                    .expect_err(&format!("zz_typo before `{name}`"))
                    .to_string();
                assert!(e.contains("zz_typo"), "before `{name}`: {e}");
            }
        }
        // Job, City, Ground, LookAt, Point, Spot, Sun, Outputs, the pipeline,
        // chcpp, reference, a named pipeline and its pipeline and chcpp.
        let expected = [
            "version",
            "seed",
            "size",
            "eye",
            "position",
            "elevation_deg",
            "masks",
            "stencil",
            "batch",
            "depth_error",
            "name",
            "tile",
            "scene",
        ];
        for name in expected {
            assert!(
                levels.contains(name),
                "no struct starting with `{name}`: {levels:?}"
            );
        }
    }

    /// A fraction where a whole number belongs names the field and the
    /// number (ron said "Expected comma").
    #[test]
    fn fractions_for_counts_name_the_field() {
        let e = parse("(scene: City(()), frames: 2.5)")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`frames` must be a whole number, not 2.5"),
            "{e}"
        );
        let e = parse("(scene: City(()),\n resolution: (800.5, 600))")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("test.ron:2:") && e.contains("whole number, not 800.5"),
            "{e}"
        );
        let e = parse("(scene: City((blocks_x: 2e3)))")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`blocks_x` must be a whole number, not 2e3"),
            "{e}"
        );
        // Other errors keep the parser's message: a missing comma, a float
        // field, a hexadecimal number, a number where a light belongs.
        for (text, said) in [
            ("(scene: City(()) frames: 8)", "Expected comma"),
            ("(scene: City(()), resolution: (800, 600, 1.5))", ""),
            ("(scene: City(()), frames: 0x1.5)", ""),
            ("(scene: City(()), lights: [1.5])", ""),
            (
                "(scene: City(()), camera: Fixed((eye: (0.0, 1.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 60.0 1.5, near: 0.1)))",
                "Expected comma",
            ),
        ] {
            let e = parse(text).unwrap_err().to_string();
            assert!(!e.contains("whole number") && e.contains(said), "{text}: {e}");
        }
    }

    /// A byte-order mark is accepted; invalid UTF-8 is named with its line
    /// and column (it once said "Expected opening `(`" and gave no position).
    #[test]
    fn byte_order_marks_and_invalid_utf8() {
        let dir = testkit::scratch_dir("job_utf8");
        let bom = dir.join("bom.ron");
        std::fs::write(&bom, "\u{feff}(scene: City(()), frames: 2)").unwrap();
        assert_eq!(Job::from_file(&bom).unwrap().frame_count(), 2);
        let bad = dir.join("latin1.ron");
        std::fs::write(&bad, b"(\n  scene: City(()),\n  // caf\xe9\n)").unwrap();
        let e = Job::from_file(&bad).unwrap_err().to_string();
        assert!(e.contains("latin1.ron:3:9") && e.contains("0xe9"), "{e}");
    }

    /// A misspelled field inside a light variant or a camera pose is an
    /// error naming it, not a silently dropped value (`rnage` once ran with
    /// `range: None`, `fov_x_deg` was ignored).
    #[test]
    fn misspelled_light_and_pose_fields_are_rejected() {
        for (text, field) in [
            (
                "(scene: City(()), lights: [Point(position: (0.0, 9.0, 0.0), rnage: Some(1.0))])",
                "rnage",
            ),
            (
                "(scene: City(()), lights: [Spot(position: (0.0, 9.0, 0.0), direction: (0.0, -1.0, 0.0), apex_deg: 40.0, far: 1.0)])",
                "far",
            ),
            (
                "(scene: City(()), camera: Fixed((eye: (0.0, 1.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 60.0, near: 0.1, fov_x_deg: 80.0)))",
                "fov_x_deg",
            ),
        ] {
            let e = parse(text).unwrap_err().to_string();
            assert!(e.contains(field), "{field}: {e}");
        }
    }

    #[test]
    fn full_job_parses() {
        let j = parse(
            r#"(
                version: 1,
                scene: Group([Obj("a.obj"), City((seed: 7))]),
                ground: Some((size: 100.0, y: 0.0)),
                resolution: (320, 240),
                camera: Sequence([
                    (eye: (0.0, 1.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 60.0, near: 0.1),
                    (eye: (5.0, 5.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 60.0, near: 0.1),
                ]),
                lights: [
                    Point(position: (0.0, 10.0, 0.0)),
                    Spot(position: (0.0, 10.0, 0.0), direction: (0.0, -1.0, 0.0), apex_deg: 60.0, range: Some(50.0)),
                    Directional((0.3, -1.0, 0.2)),
                    Sun(elevation_deg: 35.0, azimuth_deg: 30.0),
                    AboveScene(1.5),
                    Named("light"),
                ],
                outputs: (masks: true, shaded: false),
                pipeline: (method: zfail, stencil: db, scissor: true, two_sided: true, reference_every: 2),
                pipelines: [(name: "bf"), (name: "zp+", pipeline: (method: zpplus, stencil_bits: wide))],
            )"#,
        )
        .unwrap();
        assert_eq!(j.frame_count(), 2);
        assert_eq!(j.lights.len(), 6);
        assert_eq!(j.pipeline.method, MethodChoice::ZFail);
        assert_eq!(j.pipeline.stencil, StencilBackend::Db);
        assert!(j.pipeline.scissor);
        assert!(j.pipeline.reference_options().two_sided);
        let o = j.pipeline.shadow_options();
        assert!(o.two_sided && o.depth_bounds && o.scissor);
        assert_eq!(j.pipelines.len(), 2);
        assert_eq!(j.pipelines[0].pipeline, PipelineOptions::default());
        assert_eq!(j.pipelines[1].pipeline.method, MethodChoice::ZpPlus);
    }

    #[test]
    fn errors_name_line_and_column_or_field() {
        let e = parse("(\n  scene: Obj(\"a.obj\"),\n  colour: 3,\n)")
            .unwrap_err()
            .to_string();
        assert!(e.contains("test.ron:3:"), "{e}");
        assert!(e.contains("colour"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), resolution: (0, 10))")
            .unwrap_err()
            .to_string();
        assert!(e.contains("resolution"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), version: 2)")
            .unwrap_err()
            .to_string();
        assert!(e.contains("version"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), lights: [Spot(position: (0.0,1.0,0.0), direction: (0.0,0.0,0.0), apex_deg: 30.0)])")
            .unwrap_err()
            .to_string();
        assert!(e.contains("lights[0]") && e.contains("direction"), "{e}");
        let e = parse("(resolution: (10, 10))").unwrap_err().to_string();
        assert!(e.contains("scene"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), pipeline: (stencil: hier))")
            .unwrap_err()
            .to_string();
        assert!(e.contains("hier"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), pipeline: (stencil: h, tile: 12))")
            .unwrap_err()
            .to_string();
        assert!(e.contains("pipeline.tile") && e.contains("12"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), pipeline: (stencil: hybrid, map_size: 5))")
            .unwrap_err()
            .to_string();
        assert!(e.contains("pipeline.map_size"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), pipeline: (counters: bits16))")
            .unwrap_err()
            .to_string();
        assert!(e.contains("bits16"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), pipeline: (reference: (two_sided: true)))")
            .unwrap_err()
            .to_string();
        assert!(e.contains("pipeline.reference.two_sided"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), pipelines: [(name: \"a\"), (name: \"a\")])")
            .unwrap_err()
            .to_string();
        assert!(e.contains("pipelines[1].name"), "{e}");
    }
}
