//! Wavefront OBJ loader: positions and faces only, one object per `o`/`g`
//! group, n-gons triangulated by constrained Delaunay triangulation.
//!
//! What: every `o`/`g` group with faces becomes one object (one [`Mesh`] and
//! one root node, both named after the group); faces before any `o`/`g` go
//! into an object named after the file stem. Normals, texture coordinates,
//! materials and `.mtl` files are ignored — only positions matter for shadow
//! volumes — so a missing or broken `.mtl` never fails a file. Triangles are
//! kept as written; quads and larger faces are triangulated by constrained
//! Delaunay triangulation in their best-fit plane (see `triangulate`), not
//! fanned, so concave faces keep their true area and their winding.
//!
//! Far from the origin: positions are also parsed in f64. Geometry whose
//! centre lies far from the origin compared with its size (city.obj's
//! buildings near 1e7) is recentred: the mesh holds `f32(p − centre)` and its
//! node the translation, in f64 (see [`super::recentre`]). Groups whose bounds
//! touch share one centre, so their common vertices stay bit-identical. Other
//! meshes keep the file's f32 values and an identity transform.
//!
//! Why the text is sanitized before tobj parses it: tobj 4.0.5 panics (in
//! debug builds) on out-of-range texture/normal indices, silently drops a
//! first line that starts with a UTF-8 byte-order mark, fails the whole file
//! on any non-UTF-8 byte, turns `l` polylines into filled faces, fails on
//! `1.#INF` but accepts `nan`/`inf`, and reports bad indices without a line
//! number. So this module decodes the bytes itself (UTF-8 lossily, UTF-16 by
//! its byte-order mark), joins `\` continuation lines, validates every `v`
//! and `f` line — naming the line on error — and hands tobj only `v x y z`,
//! `f` lines of absolute position indices, and `g name` lines. `l` and `p`
//! statements are dropped with a warning; everything else (`vt`, `vn`,
//! `usemtl`, `mtllib`, `s`, ...) is ignored. tobj then groups the faces into
//! models (loaded untriangulated) and this module triangulates them.

use super::triangulate::{triangulate, Outcome};
use crate::{Error, Mesh, Result, SceneGraph, Transform};
use glam::{DVec3, Vec3};
use std::borrow::Cow;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

/// How many line numbers a summarizing warning lists before "...".
const LINES_IN_WARNING: usize = 8;

/// Loads an `.obj` file.
///
/// One object per `o`/`g` group that has faces (consecutive groups of the same
/// name are one object; a group far from the origin is recentred, its
/// translation in the node's transform); faces before any group, and groups
/// without a name, belong to an object named after the file stem. Only positions are read: no
/// `.mtl` is opened. A file without faces (empty, or only `v`/`l`/`p` lines)
/// loads as an empty graph with a warning. Load warnings (dropped `l`/`p`
/// statements, faces with fewer than three corners, polygons that had to be
/// ear-clipped, groups whose faces are all degenerate, undecodable bytes) are
/// recorded in the graph, each starting with the file name.
///
/// # Errors
/// [`Error::Io`] when the file cannot be read; [`Error::Load`] naming the file
/// and the line for an unparsable or non-finite coordinate, a face index that
/// is 0, unparsable, or refers to a vertex not defined before its line.
pub fn load_obj(path: &Path) -> Result<SceneGraph> {
    let bytes = super::input::read_file(path, None)?;
    load_obj_bytes(&bytes, path)
}

/// Loads every `*.obj` file (extension compared case-insensitively) of the
/// directory `dir`, sorted by file name; each file's objects come in file order.
///
/// # Errors
/// [`Error::Io`] when the directory or a file cannot be read; [`Error::Load`]
/// when the directory holds no `.obj` file, or the first file error (naming
/// that file) as in [`load_obj`].
pub fn load_obj_dir(dir: &Path) -> Result<SceneGraph> {
    let io = |source| Error::Io {
        path: dir.to_path_buf(),
        referenced_from: None,
        source,
    };
    let mut files: Vec<PathBuf> = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        let is_obj = path
            .extension()
            .is_some_and(|e| e.to_string_lossy().eq_ignore_ascii_case("obj"));
        if is_obj && path.is_file() {
            files.push(path);
        }
    }
    if files.is_empty() {
        return Err(Error::Load {
            file: dir.to_path_buf(),
            element: "directory".into(),
            message: "contains no .obj file".into(),
        });
    }
    files.sort_by(|a, b| a.file_name().cmp(&b.file_name()));
    let mut graph = SceneGraph::new();
    for file in &files {
        graph.merge(load_obj(file)?);
    }
    Ok(graph)
}

/// True when some line starts with a statement of the OBJ format (any
/// geometry, grouping, material or free-form keyword); comments and blank
/// lines do not count.
fn has_obj_statement(text: &str) -> bool {
    const KEYWORDS: &[&str] = &[
        "v",
        "vt",
        "vn",
        "vp",
        "f",
        "fo",
        "l",
        "p",
        "o",
        "g",
        "s",
        "mg",
        "usemtl",
        "mtllib",
        "cstype",
        "deg",
        "bmat",
        "step",
        "curv",
        "curv2",
        "surf",
        "parm",
        "trim",
        "hole",
        "scrv",
        "sp",
        "end",
        "con",
        "lod",
        "shadow_obj",
        "trace_obj",
        "bevel",
        "c_interp",
        "d_interp",
        "usemap",
        "maplib",
        "ctech",
        "stech",
    ];
    text.lines()
        .filter_map(|l| l.split_whitespace().next())
        .any(|k| KEYWORDS.contains(&k))
}

/// Loads OBJ text from memory (for fuzzing and tests). `file` names the
/// source in errors and warnings and gives the name of the object that holds
/// faces before any `o`/`g` (its file stem). No `.mtl` is read.
///
/// # Errors
/// As [`load_obj`], except that nothing is read from disk.
pub fn load_obj_bytes(bytes: &[u8], file: &Path) -> Result<SceneGraph> {
    let mut graph = SceneGraph::new();
    let shown = file.display();
    let (text, lossy) = decode(bytes);
    if lossy {
        graph.warn(format!(
            "{shown}: not valid UTF-8 (or UTF-16); undecodable bytes were replaced"
        ));
    }
    let stem = file
        .file_stem()
        .map(|s| s.to_string_lossy().trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "obj".to_string());
    if !has_obj_statement(&text) {
        graph.warn(format!(
            "{shown}: no OBJ statement (`v`, `f`, `o`, `g`, ...) in {} lines: is this an OBJ file?",
            text.lines().count()
        ));
    }
    let clean = sanitize(&text, file, &stem)?;
    clean.warn(&mut graph, file);
    let models = parse_with_tobj(&clean.text, file)?;
    build_objects(models, &clean, file, &mut graph)?;
    Ok(graph)
}

/// Decodes the file's bytes to text: UTF-16 LE/BE by their byte-order mark,
/// otherwise UTF-8 without its byte-order mark, lossily. Returns the text and
/// whether anything had to be replaced.
fn decode(bytes: &[u8]) -> (Cow<'_, str>, bool) {
    let utf16 = |be: bool| {
        let units = bytes[2..].chunks_exact(2).map(|c| {
            let pair = [c[0], c[1]];
            if be {
                u16::from_be_bytes(pair)
            } else {
                u16::from_le_bytes(pair)
            }
        });
        let mut lossy = !bytes.len().is_multiple_of(2);
        let text: String = char::decode_utf16(units)
            .map(|c| {
                c.unwrap_or_else(|_| {
                    lossy = true;
                    char::REPLACEMENT_CHARACTER
                })
            })
            .collect();
        (Cow::Owned(text), lossy)
    };
    match bytes {
        [0xFF, 0xFE, ..] => utf16(false),
        [0xFE, 0xFF, ..] => utf16(true),
        _ => {
            let body = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
            let text = String::from_utf8_lossy(body);
            let lossy = matches!(text, Cow::Owned(_));
            (text, lossy)
        }
    }
}

/// The text handed to tobj plus what was learned while writing it.
#[derive(Default)]
struct Sanitized {
    /// `g`, `v` and `f` lines only, validated and normalized.
    text: String,
    /// Source line of each face written, in order.
    face_lines: Vec<usize>,
    /// Every `v` position as parsed in f32 (divided by w in f32), the values
    /// tobj sees; a mesh that is not recentred keeps exactly these.
    positions: Vec<Vec3>,
    /// Every `v` position parsed in f64 (divided by w in f64), from which a
    /// recentred mesh's local vertices are formed before rounding to f32.
    positions_f64: Vec<DVec3>,
    /// Zero-based position indices of every face written, concatenated.
    face_corners: Vec<u32>,
    /// Where each face's corners start in `face_corners` (one more entry
    /// than faces: the last is `face_corners.len()`).
    face_starts: Vec<usize>,
    /// Lines of dropped `l` statements.
    polylines: Vec<usize>,
    /// Lines of dropped `p` statements.
    points: Vec<usize>,
    /// Lines of faces with fewer than three corners (dropped).
    short_faces: Vec<usize>,
    /// Lines of free-form geometry statements (dropped).
    freeform: Vec<usize>,
}

impl Sanitized {
    fn warn(&self, graph: &mut SceneGraph, file: &Path) {
        let shown = file.display();
        if !self.polylines.is_empty() || !self.points.is_empty() {
            let first = [self.polylines.first(), self.points.first()]
                .into_iter()
                .flatten()
                .min()
                .copied()
                .unwrap_or(0);
            graph.warn(format!(
                "{shown}: dropped {} `l` (polyline) and {} `p` (point) statements (the first at line {first}): only faces are loaded",
                self.polylines.len(),
                self.points.len(),
            ));
        }
        if !self.short_faces.is_empty() {
            graph.warn(format!(
                "{shown}: dropped {} faces with fewer than 3 corners ({})",
                self.short_faces.len(),
                line_list(&self.short_faces)
            ));
        }
        if !self.freeform.is_empty() {
            graph.warn(format!(
                "{shown}: ignored {} free-form geometry statements (curv/curv2/surf) ({})",
                self.freeform.len(),
                line_list(&self.freeform)
            ));
        }
    }
}

/// `line 3`, `lines 3, 7, 9, ...`.
fn line_list(lines: &[usize]) -> String {
    let shown: Vec<String> = lines
        .iter()
        .take(LINES_IN_WARNING)
        .map(usize::to_string)
        .collect();
    let more = if lines.len() > LINES_IN_WARNING {
        ", ..."
    } else {
        ""
    };
    match lines.len() {
        1 => format!("line {}", shown.join("")),
        _ => format!("lines {}{more}", shown.join(", ")),
    }
}

/// Logical lines: physical lines split at `\n` (or lone `\r`), `\r\n`
/// handled, and lines ending in `\` joined with the next. Yields
/// `(first physical line number, text)`.
fn logical_lines(text: &str) -> impl Iterator<Item = (usize, Cow<'_, str>)> {
    let separator = if !text.contains('\n') && text.contains('\r') {
        '\r'
    } else {
        '\n'
    };
    let mut physical = text
        .split(separator)
        .map(|l| l.strip_suffix('\r').unwrap_or(l))
        .enumerate()
        .map(|(i, l)| (i + 1, l));
    std::iter::from_fn(move || {
        let (number, first) = physical.next()?;
        let Some(head) = first.trim_end().strip_suffix('\\') else {
            return Some((number, Cow::Borrowed(first)));
        };
        let mut joined = head.to_string();
        for (_, next) in physical.by_ref() {
            joined.push(' ');
            match next.trim_end().strip_suffix('\\') {
                Some(head) => joined.push_str(head),
                None => {
                    joined.push_str(next);
                    break;
                }
            }
        }
        Some((number, Cow::Owned(joined)))
    })
}

/// The line without its comment: `#` at the start or after whitespace starts one.
fn strip_comment(line: &str) -> &str {
    let bytes = line.as_bytes();
    let cut = (0..bytes.len())
        .find(|&i| bytes[i] == b'#' && (i == 0 || bytes[i - 1].is_ascii_whitespace()))
        .unwrap_or(bytes.len());
    &line[..cut]
}

/// Validates and normalizes the OBJ text for tobj (see the module docs).
fn sanitize(text: &str, file: &Path, stem: &str) -> Result<Sanitized> {
    let error = |line: usize, message: String| Error::Load {
        file: file.to_path_buf(),
        element: format!("line {line}"),
        message,
    };
    let mut out = Sanitized::default();
    out.text.reserve(text.len() / 2);
    // Faces before any o/g belong to an object named after the file stem.
    let _ = writeln!(out.text, "g {stem}");
    let mut vertices: usize = 0;
    let mut corners: Vec<u64> = Vec::new();
    for (number, line) in logical_lines(text) {
        let line = strip_comment(&line);
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        match keyword {
            "v" => {
                let mut xyz = [0f32; 3];
                let mut wide = [0f64; 3];
                let mut count = 0;
                for ((slot, wslot), word) in xyz.iter_mut().zip(wide.iter_mut()).zip(words.by_ref())
                {
                    let parse_error = || {
                        error(
                            number,
                            format!("cannot parse vertex coordinate `{word}` as a number"),
                        )
                    };
                    *slot = word.parse::<f32>().map_err(|_| parse_error())?;
                    *wslot = word.parse::<f64>().map_err(|_| parse_error())?;
                    if !slot.is_finite() || !wslot.is_finite() {
                        return Err(error(
                            number,
                            format!("vertex coordinate `{word}` is not a finite f32 (NaN, infinite or out of range)"),
                        ));
                    }
                    count += 1;
                }
                if count < 3 {
                    return Err(error(
                        number,
                        format!("a vertex needs 3 coordinates, found {count}"),
                    ));
                }
                let rest: Vec<&str> = words.collect();
                // One more value is the homogeneous w (tobj divides by it);
                // three or more are vertex colors, which are ignored.
                if let [w] = rest[..] {
                    let w_error = || {
                        error(
                            number,
                            format!("cannot parse vertex weight `{w}` as a number"),
                        )
                    };
                    let w32 = w.parse::<f32>().map_err(|_| w_error())?;
                    let w64 = w.parse::<f64>().map_err(|_| w_error())?;
                    if w32 == 0.0 || !w32.is_finite() || w64 == 0.0 || !w64.is_finite() {
                        return Err(error(
                            number,
                            format!("vertex weight w = {w32} is not a finite non-zero number"),
                        ));
                    }
                    xyz = xyz.map(|c| c / w32);
                    wide = wide.map(|c| c / w64);
                }
                if xyz.iter().any(|c| !c.is_finite())
                    || wide
                        .iter()
                        .any(|&c| !c.is_finite() || !(c as f32).is_finite())
                {
                    return Err(error(
                        number,
                        "vertex coordinates divided by w are not finite".into(),
                    ));
                }
                let [x, y, z] = xyz;
                let _ = writeln!(out.text, "v {x:e} {y:e} {z:e}");
                out.positions.push(Vec3::from_array(xyz));
                out.positions_f64.push(DVec3::from_array(wide));
                vertices += 1;
            }
            "f" => {
                corners.clear();
                for word in words {
                    let index_text = word.split('/').next().unwrap_or("");
                    let index: i64 = index_text
                        .parse()
                        .map_err(|_| error(number, format!("cannot parse face vertex `{word}`")))?;
                    let defined = vertices as i64;
                    let absolute = match index {
                        0 => {
                            return Err(error(
                                number,
                                "face index 0 is invalid (OBJ indices start at 1)".into(),
                            ))
                        }
                        i if i > 0 && i <= defined => i,
                        i if i < 0 && defined + i >= 0 => defined + i + 1,
                        i => {
                            return Err(error(
                                number,
                                format!(
                                    "face index {i} is out of range: {defined} vertices are defined before this line"
                                ),
                            ))
                        }
                    };
                    corners.push(absolute as u64);
                }
                if corners.len() < 3 {
                    out.short_faces.push(number);
                    continue;
                }
                out.text.push('f');
                for c in &corners {
                    let _ = write!(out.text, " {c}");
                }
                out.text.push('\n');
                out.face_lines.push(number);
                out.face_starts.push(out.face_corners.len());
                // Absolute indices are 1..=vertices, and vertices fit in u32
                // (checked below before anything uses them).
                out.face_corners
                    .extend(corners.iter().map(|&c| (c - 1) as u32));
            }
            "o" | "g" => {
                let name = line.trim_start()[1..].trim();
                let name = if name.is_empty() { stem } else { name };
                let _ = writeln!(out.text, "g {name}");
            }
            "l" => out.polylines.push(number),
            "p" => out.points.push(number),
            "curv" | "curv2" | "surf" => out.freeform.push(number),
            _ => {}
        }
    }
    if vertices > u32::MAX as usize {
        return Err(Error::Load {
            file: file.to_path_buf(),
            element: "file".into(),
            message: format!("{vertices} vertices; at most {} are supported", u32::MAX),
        });
    }
    out.face_starts.push(out.face_corners.len());
    Ok(out)
}

/// Runs tobj (untriangulated, materials ignored) over sanitized text.
fn parse_with_tobj(text: &str, file: &Path) -> Result<Vec<tobj::Model>> {
    let options = tobj::LoadOptions {
        triangulate: false,
        single_index: false,
        ignore_points: false,
        ignore_lines: false,
    };
    let no_materials = |_: &Path| -> tobj::MTLLoadResult { Ok((Vec::new(), HashMap::new())) };
    let fail = |message: String| Error::Load {
        file: file.to_path_buf(),
        element: "file".into(),
        message,
    };
    // The text is validated, so tobj should neither fail nor panic; both are
    // still turned into errors rather than trusted.
    let parsed = catch_unwind(AssertUnwindSafe(|| {
        tobj::load_obj_buf(&mut text.as_bytes(), &options, no_materials)
    }))
    .map_err(|_| fail("the OBJ parser (tobj) panicked".into()))?;
    parsed
        .map(|(models, _)| models)
        .map_err(|e| fail(format!("the OBJ parser (tobj) failed: {e}")))
}

/// One object being assembled from consecutive tobj models of one name.
struct Group {
    name: String,
    /// Zero-based file position index of each group vertex, in first-use order.
    vertices: Vec<u32>,
    /// File position index → group vertex.
    local: HashMap<u32, u32>,
    /// Group-vertex corners of every face, concatenated.
    corners: Vec<u32>,
    /// Per face: source line and its range in `corners`.
    faces: Vec<(usize, std::ops::Range<usize>)>,
}

/// A group ready to become a mesh.
struct Built {
    name: String,
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    faces: usize,
    centre: Option<DVec3>,
}

/// Groups tobj's models (consecutive models of one name are one object),
/// takes positions from the validated text (f64, recentred when far from the
/// origin; see [`cluster_centres`]), triangulates, and adds one mesh and one
/// root node per group to `graph`.
fn build_objects(
    models: Vec<tobj::Model>,
    clean: &Sanitized,
    file: &Path,
    graph: &mut SceneGraph,
) -> Result<()> {
    let shown = file.display();
    let mut groups: Vec<Group> = Vec::new();
    let mut face = 0usize; // running face number across models
    for model in models {
        let mesh = model.mesh;
        if mesh.indices.is_empty() {
            continue;
        }
        let same = groups.last().is_some_and(|g| g.name == model.name);
        if !same {
            groups.push(Group {
                name: model.name,
                vertices: Vec::new(),
                local: HashMap::new(),
                corners: Vec::new(),
                faces: Vec::new(),
            });
        }
        let Some(group) = groups.last_mut() else {
            continue;
        };
        let arities: Vec<u32> = if mesh.face_arities.is_empty() {
            vec![3; mesh.indices.len() / 3]
        } else {
            mesh.face_arities
        };
        let mut start = 0usize;
        for arity in arities {
            let end = start + arity as usize;
            if mesh.indices.get(start..end).is_none() {
                break;
            }
            start = end;
            // tobj keeps the faces of the validated text in order, so face k
            // of its models is face k written by `sanitize`.
            let (Some(&from), Some(&to)) =
                (clean.face_starts.get(face), clean.face_starts.get(face + 1))
            else {
                break;
            };
            let line = clean.face_lines.get(face).copied().unwrap_or(0);
            face += 1;
            let global = &clean.face_corners[from..to];
            if global.len() != arity as usize {
                return Err(Error::Load {
                    file: file.to_path_buf(),
                    element: format!("line {line}"),
                    message: format!(
                        "the OBJ parser (tobj) read a face of {arity} corners where {} were written",
                        global.len()
                    ),
                });
            }
            let first = group.corners.len();
            for &g in global {
                let next = group.vertices.len() as u32;
                let k = *group.local.entry(g).or_insert_with(|| {
                    group.vertices.push(g);
                    next
                });
                group.corners.push(k);
            }
            group.faces.push((line, first..group.corners.len()));
        }
    }

    let centres = cluster_centres(&groups, &clean.positions_f64);
    let mut fallbacks: Vec<(usize, &'static str)> = Vec::new();
    let mut corners: Vec<Vec3> = Vec::new();
    let mut local: Vec<[u32; 3]> = Vec::new();
    let mut built: Vec<Built> = Vec::with_capacity(groups.len());
    for (group, centre) in groups.into_iter().zip(centres) {
        let positions: Vec<Vec3> = match centre {
            Some(c) => group
                .vertices
                .iter()
                .map(|&g| (clean.positions_f64[g as usize] - c).as_vec3())
                .collect(),
            None => group
                .vertices
                .iter()
                .map(|&g| clean.positions[g as usize])
                .collect(),
        };
        let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(group.corners.len());
        for (line, range) in &group.faces {
            let indices = &group.corners[range.clone()];
            if let [a, b, c] = *indices {
                triangles.push([a, b, c]);
                continue;
            }
            corners.clear();
            corners.extend(indices.iter().map(|&i| positions[i as usize]));
            local.clear();
            if let Outcome::Fallback(why) = triangulate(&corners, &mut local) {
                fallbacks.push((*line, why.describe()));
            }
            triangles.extend(local.iter().map(|t| t.map(|k| indices[k as usize])));
        }
        built.push(Built {
            name: group.name,
            positions,
            triangles,
            faces: group.faces.len(),
            centre,
        });
    }
    if !fallbacks.is_empty() {
        let lines: Vec<usize> = fallbacks.iter().map(|f| f.0).collect();
        graph.warn(format!(
            "{shown}: {} polygons could not be triangulated by constrained Delaunay triangulation ({}); first, at line {}: polygon {}",
            fallbacks.len(),
            line_list(&lines),
            fallbacks[0].0,
            fallbacks[0].1
        ));
    }
    if built.is_empty() {
        graph.warn(format!(
            "{shown}: no faces; the file loads as an empty scene"
        ));
    }
    for group in built {
        // Indices come from validated text and positions are finite, so
        // this cannot fail; if it does, the error names the file.
        let mesh =
            Mesh::new(group.name.clone(), &group.positions, &group.triangles).map_err(|e| {
                Error::Load {
                    file: file.to_path_buf(),
                    element: format!("object `{}`", group.name),
                    message: e.to_string(),
                }
            })?;
        if mesh.triangles().is_empty() {
            graph.warn(format!(
                "{shown}: object `{}`: all {} faces are degenerate (zero area); object skipped",
                group.name, group.faces
            ));
            continue;
        }
        let id = graph.add_mesh(mesh);
        let transform = group
            .centre
            .map_or_else(Transform::default, Transform::translation);
        graph.add_instance(&group.name, id, transform);
    }
    Ok(())
}

/// The translation each group is recentred by (see [`super::recentre`]), or
/// `None` where it keeps the file's f32 values.
///
/// Groups whose f64 bounds touch or overlap form one cluster and share one
/// centre, computed from the cluster's bounds: groups that share vertices (a
/// roof on its walls, three faces of `regr_3429812.obj`) then hold
/// bit-identical local vertices under one and the same transform, so the
/// eye pass and the volumes see their common edges exactly where they met
/// before. Sort and sweep along x; union-find over the overlaps.
fn cluster_centres(groups: &[Group], positions: &[DVec3]) -> Vec<Option<DVec3>> {
    let bounds: Vec<(DVec3, DVec3)> = groups
        .iter()
        .map(|g| {
            g.vertices.iter().fold(
                (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
                |(lo, hi), &v| {
                    let p = positions[v as usize];
                    (lo.min(p), hi.max(p))
                },
            )
        })
        .collect();
    let mut parent: Vec<usize> = (0..groups.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut order: Vec<usize> = (0..groups.len()).collect();
    order.sort_by(|&a, &b| bounds[a].0.x.total_cmp(&bounds[b].0.x));
    let mut active: Vec<usize> = Vec::new();
    for &i in &order {
        let (lo, hi) = bounds[i];
        active.retain(|&j| bounds[j].1.x >= lo.x);
        for &j in &active {
            let (jlo, jhi) = bounds[j];
            if jlo.cmple(hi).all() && lo.cmple(jhi).all() {
                let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                parent[a.max(b)] = a.min(b);
            }
        }
        active.push(i);
    }
    let mut cluster: Vec<(DVec3, DVec3)> =
        vec![(DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)); groups.len()];
    let roots: Vec<usize> = (0..groups.len()).map(|i| root(&mut parent, i)).collect();
    for (i, &r) in roots.iter().enumerate() {
        cluster[r] = (cluster[r].0.min(bounds[i].0), cluster[r].1.max(bounds[i].1));
    }
    roots
        .iter()
        .map(|&r| super::recentre::recentre(cluster[r].0, cluster[r].1))
        .collect()
}
