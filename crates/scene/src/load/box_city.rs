//! Box-city loader: the `citysc 1` benchmark format of
//! `../shared/data/bench/README.md` — axis-aligned box buildings on a ground
//! quad, with named cameras and one point light — used to compare shadowcull
//! with other systems on exactly the same input.
//!
//! # What it builds
//! - Box `k` (line `k` of the box list) becomes object `k`: its own mesh
//!   ([`box_mesh`], 12 triangles in the README's corner and face order) in
//!   world coordinates with the identity transform. One mesh per box, not one
//!   shared unit cube with per-object transforms: a scaled-and-translated unit
//!   cube is only exact when the transform path rounds exactly, whereas here
//!   every world-space vertex is the file's own number converted to f32 — the
//!   README's coordinates are multiples of 0.25, so bit-exact. (A number that
//!   is not exact in f32 is rounded to nearest and counted in one warning.)
//! - The `ground` line becomes the last object: one up-facing quad (2
//!   triangles, counter-clockwise seen from +y) at its y.
//! - Cameras: every `camera` name as a [`LookAt`] (eye, target, up, fovy,
//!   near) — they repeat per resolution; the first line of each name counts.
//! - Light: `("light", Light::Point { position, range: None })`.
//! - Paths: `street` — a [`CameraPath::Dolly`] of the street camera moving
//!   1 m per frame toward −z (eye and target); `bird` — a
//!   [`CameraPath::Orbit`] of the bird camera about the vertical axis through
//!   the centre of the boxes' bounds in x and z (y = 0), 1° per frame.
//!
//! `view`, `proj` and `viewproj` lines are checked for shape and ignored:
//! shadowcull builds its own reversed-Z projection. Errors name the file and
//! the 1-based line.

use super::input::read_file;
use crate::loaded::Loaded;
use crate::procedural::analytic::{box_mesh, horizontal_quad};
use crate::{CameraPath, Error, Light, LookAt, Result, SceneGraph, Transform};
use glam::DVec3;
use std::path::{Path, PathBuf};

/// Metres the `street` path moves per frame (toward −z).
pub const STREET_METRES_PER_FRAME: f64 = 1.0;
/// Degrees the `bird` path turns per frame (counter-clockwise seen from above).
pub const BIRD_DEGREES_PER_FRAME: f64 = 1.0;

/// Shortest possible box line (`0 0 0 0 0 0` plus a newline): bounds the
/// declared box count by the file's real length.
const MIN_BOX_LINE: usize = 12;

/// Loads a `citysc 1` box-city file (see the module doc for what it builds).
///
/// # Errors
/// [`Error::Io`] when the file cannot be read; otherwise as
/// [`load_box_city_str`], plus [`Error::Load`] for bytes that are not UTF-8.
pub fn load_box_city(path: &Path) -> Result<Loaded> {
    let bytes = read_file(path, None)?;
    let text = std::str::from_utf8(&bytes).map_err(|e| {
        let line = bytes[..e.valid_up_to()]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
            + 1;
        Error::Load {
            file: path.to_path_buf(),
            element: format!("line {line}"),
            message: "not valid UTF-8 text".into(),
        }
    })?;
    load_box_city_str(text, path)
}

/// Parses box-city text; `file` is only used to name errors.
///
/// # Errors
/// [`Error::Load`] naming `file` and `line N` for: a missing or wrong
/// `citysc 1` header, an unknown keyword, a wrong number of fields, a field
/// that is not a number (or is NaN or infinite), a box or ground whose min is
/// above its max (or a box with zero extent), a ground that is not horizontal,
/// an invalid camera (eye = target, up parallel to the view, fov outside
/// (0°, 180°), near ≤ 0), a second `light` or `ground` line, a box count that
/// does not match the box lines, content after `end`, or a missing `end`.
pub fn load_box_city_str(text: &str, file: &Path) -> Result<Loaded> {
    Parser {
        file: file.to_path_buf(),
    }
    .parse(text)
}

struct Parser {
    file: PathBuf,
}

/// One significant line: its 1-based number and its fields.
struct Line<'a> {
    number: usize,
    fields: Vec<&'a str>,
}

impl Parser {
    fn err(&self, line: usize, message: impl Into<String>) -> Error {
        Error::Load {
            file: self.file.clone(),
            element: format!("line {line}"),
            message: message.into(),
        }
    }

    fn num(&self, line: &Line, i: usize) -> Result<f64> {
        let Some(s) = line.fields.get(i) else {
            return Err(self.err(line.number, format!("field {} is missing", i + 1)));
        };
        match s.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(_) => Err(self.err(
                line.number,
                format!("field {} (`{s}`) must be a finite number", i + 1),
            )),
            Err(_) => Err(self.err(
                line.number,
                format!("field {} (`{s}`) is not a number", i + 1),
            )),
        }
    }

    fn vec3(&self, line: &Line, i: usize) -> Result<DVec3> {
        Ok(DVec3::new(
            self.num(line, i)?,
            self.num(line, i + 1)?,
            self.num(line, i + 2)?,
        ))
    }

    fn uint(&self, line: &Line, i: usize) -> Result<u64> {
        let s = line.fields.get(i).copied().unwrap_or("");
        s.parse::<u64>().map_err(|_| {
            self.err(
                line.number,
                format!("field {} (`{s}`) is not a non-negative integer", i + 1),
            )
        })
    }

    fn expect_len(&self, line: &Line, n: usize) -> Result<()> {
        if line.fields.len() == n {
            Ok(())
        } else {
            Err(self.err(
                line.number,
                format!(
                    "`{}` line has {} fields, expected {n}",
                    line.fields[0],
                    line.fields.len()
                ),
            ))
        }
    }

    fn expect_word(&self, line: &Line, i: usize, word: &str) -> Result<()> {
        match line.fields.get(i) {
            Some(&w) if w == word => Ok(()),
            other => Err(self.err(
                line.number,
                format!(
                    "field {} should be `{word}`, found `{}`",
                    i + 1,
                    other.copied().unwrap_or("")
                ),
            )),
        }
    }

    /// `camera <name> <w> <h> eye x y z target x y z up x y z fovy <deg> near <n> far <f> eps <e>`
    fn camera(&self, line: &Line) -> Result<(String, LookAt)> {
        if line.fields.len() < 4 {
            return Err(self.err(line.number, "`camera` needs a name, width and height"));
        }
        self.uint(line, 2)?;
        self.uint(line, 3)?;
        let (mut eye, mut target, mut up, mut fovy, mut near) = (None, None, None, None, None);
        let mut i = 4;
        while i < line.fields.len() {
            let key = line.fields[i];
            match key {
                "eye" => eye = Some(self.vec3(line, i + 1)?),
                "target" => target = Some(self.vec3(line, i + 1)?),
                "up" => up = Some(self.vec3(line, i + 1)?),
                "fovy" => fovy = Some(self.num(line, i + 1)?),
                "near" => near = Some(self.num(line, i + 1)?),
                "far" | "eps" => {
                    let s = line.fields.get(i + 1).copied().unwrap_or("");
                    if s.parse::<f64>().map_or(true, |v| v.is_nan()) {
                        return Err(
                            self.err(line.number, format!("`{key}` value `{s}` is not a number"))
                        );
                    }
                }
                _ => return Err(self.err(line.number, format!("unknown camera field `{key}`"))),
            }
            i += if matches!(key, "eye" | "target" | "up") {
                4
            } else {
                2
            };
        }
        let missing = |what: &str| self.err(line.number, format!("camera has no `{what}`"));
        let pose = LookAt {
            eye: eye.ok_or_else(|| missing("eye"))?,
            target: target.ok_or_else(|| missing("target"))?,
            up: up.ok_or_else(|| missing("up"))?,
            fov_y_deg: fovy.ok_or_else(|| missing("fovy"))?,
            near: near.ok_or_else(|| missing("near"))?,
        };
        pose.camera(1.0)
            .map_err(|e| self.err(line.number, e.to_string()))?;
        Ok((line.fields[1].to_string(), pose))
    }

    /// A box line: six numbers, min strictly below max on every axis.
    fn box_line(&self, line: &Line, k: usize, inexact: &mut usize) -> Result<(DVec3, DVec3)> {
        if line.fields.len() != 6 {
            return Err(self.err(
                line.number,
                format!(
                    "box {k}: expected 6 numbers, found {} fields",
                    line.fields.len()
                ),
            ));
        }
        let min = self.vec3(line, 0)?;
        let max = self.vec3(line, 3)?;
        for (axis, lo, hi) in [
            ("x", min.x, max.x),
            ("y", min.y, max.y),
            ("z", min.z, max.z),
        ] {
            if lo > hi {
                return Err(self.err(
                    line.number,
                    format!("box {k}: min {axis} {lo} is above max {axis} {hi}"),
                ));
            }
            if lo == hi {
                return Err(self.err(line.number, format!("box {k}: zero extent along {axis}")));
            }
        }
        *inexact += min
            .to_array()
            .iter()
            .chain(&max.to_array())
            .filter(|&&v| f64::from(v as f32) != v)
            .count();
        Ok((min, max))
    }

    fn parse(&self, text: &str) -> Result<Loaded> {
        let mut lines = text.lines().enumerate().filter_map(|(i, l)| {
            let t = l.trim();
            (!t.is_empty() && !t.starts_with('#')).then(|| Line {
                number: i + 1,
                fields: t.split_whitespace().collect(),
            })
        });
        let last_line = text.lines().count().max(1);
        let eof = |what: &str| self.err(last_line, format!("unexpected end of file: {what}"));

        let header = lines
            .next()
            .ok_or_else(|| eof("missing header `citysc 1`"))?;
        if header.fields.first() != Some(&"citysc") {
            return Err(self.err(header.number, "missing header `citysc 1`"));
        }
        self.expect_len(&header, 2)?;
        if header.fields[1] != "1" {
            return Err(self.err(
                header.number,
                format!(
                    "unsupported citysc version `{}` (expected 1)",
                    header.fields[1]
                ),
            ));
        }

        let mut ground: Option<(usize, DVec3, DVec3)> = None;
        let mut light: Option<DVec3> = None;
        let mut cameras: Vec<(String, LookAt)> = Vec::new();
        let count_line = loop {
            let line = lines.next().ok_or_else(|| eof("missing `boxes <N>`"))?;
            match line.fields[0] {
                "seed" => {
                    self.expect_len(&line, 2)?;
                    self.uint(&line, 1)?;
                }
                "grid" => {
                    self.expect_len(&line, 6)?;
                    self.uint(&line, 1)?;
                    self.expect_word(&line, 2, "pitch")?;
                    self.num(&line, 3)?;
                    self.expect_word(&line, 4, "street")?;
                    self.num(&line, 5)?;
                }
                "ground" => {
                    self.expect_len(&line, 7)?;
                    if ground.is_some() {
                        return Err(self.err(line.number, "second `ground` line"));
                    }
                    let (min, max) = (self.vec3(&line, 1)?, self.vec3(&line, 4)?);
                    if min.y != max.y {
                        return Err(
                            self.err(line.number, "ground must be horizontal (min y = max y)")
                        );
                    }
                    if min.x >= max.x || min.z >= max.z {
                        return Err(self.err(line.number, "ground min x, z must be below max x, z"));
                    }
                    ground = Some((line.number, min, max));
                }
                "light" => {
                    self.expect_len(&line, 4)?;
                    if light.is_some() {
                        return Err(self.err(line.number, "second `light` line"));
                    }
                    light = Some(self.vec3(&line, 1)?);
                }
                "camera" => {
                    let (name, pose) = self.camera(&line)?;
                    if !cameras.iter().any(|(n, _)| *n == name) {
                        cameras.push((name, pose));
                    }
                }
                "view" | "proj" | "viewproj" => {
                    self.expect_len(&line, 20)?;
                    self.uint(&line, 2)?;
                    self.uint(&line, 3)?;
                    for i in 4..20 {
                        self.num(&line, i)?;
                    }
                }
                "boxes" => {
                    self.expect_len(&line, 2)?;
                    break line;
                }
                "end" => return Err(self.err(line.number, "`end` before `boxes <N>`")),
                other => return Err(self.err(line.number, format!("unknown keyword `{other}`"))),
            }
        };

        let n = self.uint(&count_line, 1)?;
        if n > (text.len() / MIN_BOX_LINE) as u64 {
            return Err(self.err(
                count_line.number,
                format!("box count {n} is more than the file's length can hold"),
            ));
        }
        let n = n as usize;
        let mut graph = SceneGraph::new();
        let mut inexact = 0;
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for k in 0..n {
            let line = lines
                .next()
                .ok_or_else(|| eof(&format!("read {k} of {n} boxes, and no `end`")))?;
            if line.fields[0] == "end" {
                return Err(self.err(
                    line.number,
                    format!("`end` after {k} boxes, but `boxes` declares {n}"),
                ));
            }
            let (min, max) = self.box_line(&line, k, &mut inexact)?;
            lo = lo.min(min);
            hi = hi.max(max);
            let name = format!("box {k}");
            let mesh = box_mesh(name.clone(), min.as_vec3(), max.as_vec3())
                .map_err(|e| self.err(line.number, e.to_string()))?;
            let mesh = graph.add_mesh(mesh);
            graph.add_instance(&name, mesh, Transform::default());
        }
        let end = lines
            .next()
            .ok_or_else(|| eof(&format!("all {n} boxes read, but no `end`")))?;
        if end.fields[0] != "end" {
            return Err(self.err(
                end.number,
                format!("expected `end` after {n} boxes (more box lines than `boxes` declares?)"),
            ));
        }
        self.expect_len(&end, 1)?;
        if let Some(extra) = lines.next() {
            return Err(self.err(extra.number, "content after `end`"));
        }

        if let Some((number, min, max)) = ground {
            let (min, max) = (min.as_vec3(), max.as_vec3());
            let quad = horizontal_quad("ground", [min.x, max.x], [min.z, max.z], min.y, true)
                .map_err(|e| self.err(number, e.to_string()))?;
            let mesh = graph.add_mesh(quad);
            graph.add_instance("ground", mesh, Transform::default());
        }
        if inexact > 0 {
            graph.warn(format!(
                "{inexact} box coordinates are not exact in f32 and were rounded to nearest"
            ));
        }

        let mut paths = Vec::new();
        for (name, pose) in &cameras {
            match name.as_str() {
                "street" => paths.push((
                    name.clone(),
                    CameraPath::Dolly {
                        start: *pose,
                        per_frame: DVec3::new(0.0, 0.0, -STREET_METRES_PER_FRAME),
                    },
                )),
                "bird" => {
                    let center = if n > 0 {
                        DVec3::new(0.5 * (lo.x + hi.x), 0.0, 0.5 * (lo.z + hi.z))
                    } else {
                        DVec3::new(pose.target.x, 0.0, pose.target.z)
                    };
                    paths.push((
                        name.clone(),
                        CameraPath::Orbit {
                            start: *pose,
                            center,
                            deg_per_frame: BIRD_DEGREES_PER_FRAME,
                        },
                    ));
                }
                _ => {}
            }
        }
        let lights = light
            .map(|position| {
                (
                    "light".to_string(),
                    Light::Point {
                        position,
                        range: None,
                    },
                )
            })
            .into_iter()
            .collect();
        Ok(Loaded {
            graph,
            cameras,
            paths,
            lights,
        })
    }
}
