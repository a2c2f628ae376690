//! The glTF JSON document: parsing (inside `catch_unwind`), the `asset.version`
//! check, the `extensionsRequired` policy, and bounds-checked, typed lookups of
//! single elements (`accessors[3]`, `meshes[2]`, ...).
//!
//! Elements are deserialized one at a time, when geometry first needs them, so
//! a malformed material, texture or animation never stops the geometry from
//! loading, and every error names the element it comes from.

use crate::{Error, Result};
use serde::de::DeserializeOwned;
use serde_json::{Map, Value};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

/// Where errors and warnings point: the file given to the loader.
pub(super) struct Ctx<'a> {
    file: &'a Path,
    warnings: Vec<String>,
}

impl<'a> Ctx<'a> {
    pub(super) fn new(file: &'a Path) -> Self {
        Ctx {
            file,
            warnings: Vec::new(),
        }
    }

    /// The file given to the loader.
    pub(super) fn file(&self) -> &'a Path {
        self.file
    }

    /// An [`Error::Load`] naming the file and `element`.
    pub(super) fn err(&self, element: impl Into<String>, message: impl Into<String>) -> Error {
        Error::Load {
            file: self.file.to_path_buf(),
            element: element.into(),
            message: message.into(),
        }
    }

    /// Records a warning, formatted like an error: `file: element: message`.
    pub(super) fn warn(&mut self, element: impl AsRef<str>, message: impl AsRef<str>) {
        let text = format!(
            "{}: {}: {}",
            self.file.display(),
            element.as_ref(),
            message.as_ref()
        );
        tracing::debug!(target: "shadowcull::gltf", "{text}");
        self.warnings.push(text);
    }

    /// The warnings gathered so far.
    pub(super) fn into_warnings(self) -> Vec<String> {
        self.warnings
    }
}

/// Required extensions that change geometry and that this loader does not
/// implement, with what they do. Required → error; only used → warning.
const GEOMETRY_EXTENSIONS: &[(&str, &str)] = &[
    ("KHR_draco_mesh_compression", "Draco-compressed mesh data"),
    (
        "EXT_meshopt_compression",
        "meshoptimizer-compressed buffer views",
    ),
    (
        "KHR_meshopt_compression",
        "meshoptimizer-compressed buffer views",
    ),
    ("EXT_mesh_gpu_instancing", "GPU instancing of meshes"),
];

/// Extensions this loader implements.
const SUPPORTED_EXTENSIONS: &[&str] = &["KHR_mesh_quantization", "KHR_node_visibility"];

/// Prefixes and names of extensions known to concern only appearance
/// (materials, textures, lights, animation): ignored with a warning even when
/// required, because geometry does not depend on them.
const APPEARANCE_EXTENSIONS: &[&str] = &[
    "KHR_materials_",
    "KHR_texture_",
    "EXT_texture_",
    "MSFT_texture_",
    "KHR_techniques_webgl",
    "KHR_technique_webgl",
    "KHR_lights_punctual",
    "EXT_lights_image_based",
    "KHR_animation_pointer",
    "KHR_xmp",
];

/// The top-level arrays whose elements can carry geometry-changing extensions.
const GEOMETRY_ARRAYS: &[(&str, &str)] = &[
    ("scenes", "scene"),
    ("nodes", "node"),
    ("meshes", "mesh"),
    ("accessors", "accessor"),
    ("bufferViews", "bufferView"),
    ("buffers", "buffer"),
];

/// The parsed JSON of a glTF 2.0 file whose version and required extensions
/// have been checked.
pub(super) struct Document {
    root: Map<String, Value>,
    quantization: bool,
}

impl Document {
    /// Parses `json`, checks `asset.version` and applies the extension policy.
    ///
    /// # Errors
    /// Invalid JSON, a top level that is not an object, glTF 1.0 or another
    /// unsupported version, or a required extension that changes geometry.
    pub(super) fn parse(json: &[u8], ctx: &mut Ctx<'_>) -> Result<Document> {
        let json = match json.strip_prefix(b"\xEF\xBB\xBF") {
            Some(rest) => {
                ctx.warn(
                    "JSON",
                    "starts with a UTF-8 byte order mark (not allowed); ignored",
                );
                rest
            }
            None => json,
        };
        let parsed = catch_unwind(AssertUnwindSafe(|| serde_json::from_slice::<Value>(json)))
            .map_err(|_| ctx.err("JSON", "the JSON parser panicked"))?
            .map_err(|e| ctx.err("JSON", format!("invalid JSON: {e}")))?;
        let Value::Object(root) = parsed else {
            return Err(ctx.err("JSON", "the top level is not a JSON object"));
        };
        check_version(&root, ctx)?;
        let mut used = string_list(&root, "extensionsUsed", ctx)?;
        let mut required = string_list(&root, "extensionsRequired", ctx)?;
        for list in [&mut used, &mut required] {
            list.sort_unstable();
            list.dedup();
        }
        let doc = Document {
            quantization: used
                .iter()
                .chain(&required)
                .any(|e| e == "KHR_mesh_quantization"),
            root,
        };
        doc.check_extensions(&used, &required, ctx)?;
        Ok(doc)
    }

    /// True when the file declares `KHR_mesh_quantization` (integer positions allowed).
    pub(super) fn quantization(&self) -> bool {
        self.quantization
    }

    /// A top-level field.
    pub(super) fn field(&self, key: &str) -> Option<&Value> {
        self.root.get(key)
    }

    /// Number of elements of a top-level array (0 when absent).
    ///
    /// # Errors
    /// When the field exists but is not an array.
    pub(super) fn len(&self, key: &str, ctx: &Ctx<'_>) -> Result<usize> {
        match self.root.get(key) {
            None | Some(Value::Null) => Ok(0),
            Some(Value::Array(a)) => Ok(a.len()),
            Some(_) => Err(ctx.err(key, "is not an array")),
        }
    }

    /// The raw JSON of element `index` of the top-level array `key`.
    ///
    /// # Errors
    /// When the array is absent or shorter; the error names `referrer`.
    pub(super) fn raw(
        &self,
        key: &str,
        kind: &str,
        index: usize,
        referrer: &str,
        ctx: &Ctx<'_>,
    ) -> Result<&Value> {
        let n = self.len(key, ctx)?;
        match self.root.get(key) {
            Some(Value::Array(a)) if index < n => Ok(&a[index]),
            _ => Err(ctx.err(
                referrer,
                format!("refers to {kind} {index}, but the file has {n} {kind}s"),
            )),
        }
    }

    /// Element `index` of the top-level array `key`, deserialized as `T`.
    ///
    /// # Errors
    /// A dangling index (naming `referrer`) or a malformed element (naming
    /// `kind index`).
    pub(super) fn get<T: DeserializeOwned>(
        &self,
        key: &str,
        kind: &str,
        index: usize,
        referrer: &str,
        ctx: &Ctx<'_>,
    ) -> Result<T> {
        let value = self.raw(key, kind, index, referrer, ctx)?;
        deserialize(value, &format!("{kind} {index}"), ctx)
    }

    fn check_extensions(
        &self,
        used: &[String],
        required: &[String],
        ctx: &mut Ctx<'_>,
    ) -> Result<()> {
        for name in required {
            if let Some((_, what)) = GEOMETRY_EXTENSIONS.iter().find(|(n, _)| n == name) {
                return Err(ctx.err(
                    "extensionsRequired",
                    format!(
                        "required extension {name} ({what}) is not supported: it changes geometry"
                    ),
                ));
            }
            if SUPPORTED_EXTENSIONS.contains(&name.as_str()) {
                continue;
            }
            if APPEARANCE_EXTENSIONS.iter().any(|p| name.starts_with(p)) {
                ctx.warn(
                    "extensionsRequired",
                    format!("required extension {name} concerns only appearance; ignored"),
                );
                continue;
            }
            if let Some(element) = self.geometry_element_using(name) {
                return Err(ctx.err(
                    "extensionsRequired",
                    format!("required extension {name} is not supported, and {element} uses it"),
                ));
            }
            ctx.warn(
                "extensionsRequired",
                format!(
                    "required extension {name} is not supported; ignored because no scene, node, \
                     mesh, accessor, bufferView or buffer uses it"
                ),
            );
        }
        for name in used {
            if required.contains(name) {
                continue;
            }
            if let Some((_, what)) = GEOMETRY_EXTENSIONS.iter().find(|(n, _)| n == name) {
                ctx.warn(
                    "extensionsUsed",
                    format!("extension {name} ({what}) is not supported; loading the uncompressed fallback"),
                );
            }
        }
        Ok(())
    }

    /// The first geometry element (or mesh primitive) whose `extensions` object
    /// names `ext`, as "node 3" or "mesh 2 primitive 0".
    fn geometry_element_using(&self, ext: &str) -> Option<String> {
        let has = |v: &Value| {
            v.get("extensions")
                .and_then(Value::as_object)
                .is_some_and(|e| e.contains_key(ext))
        };
        // A root-level definition alone does not touch geometry; the elements
        // that reference it do.
        for (key, kind) in GEOMETRY_ARRAYS {
            let Some(Value::Array(items)) = self.root.get(*key) else {
                continue;
            };
            for (i, item) in items.iter().enumerate() {
                if has(item) {
                    return Some(format!("{kind} {i}"));
                }
                if *key == "meshes" {
                    let prims = item.get("primitives").and_then(Value::as_array);
                    for (p, prim) in prims.into_iter().flatten().enumerate() {
                        if has(prim) {
                            return Some(format!("mesh {i} primitive {p}"));
                        }
                    }
                }
                if *key == "accessors" && item.get("sparse").is_some_and(has) {
                    return Some(format!("accessor {i}"));
                }
            }
        }
        None
    }
}

/// Deserializes one element inside `catch_unwind`, naming it in errors.
pub(super) fn deserialize<T: DeserializeOwned>(
    value: &Value,
    element: &str,
    ctx: &Ctx<'_>,
) -> Result<T> {
    catch_unwind(AssertUnwindSafe(|| T::deserialize(value)))
        .map_err(|_| ctx.err(element, "the glTF JSON parser panicked on this element"))?
        .map_err(|e| ctx.err(element, e.to_string()))
}

/// Fails unless the value at `path` inside `value` (when present) is an
/// integer that fits in a `u32`. gltf-json truncates indices and enums to 32
/// bits; checking first keeps a huge index from wrapping onto a valid one.
pub(super) fn check_u32(value: &Value, path: &[&str], element: &str, ctx: &Ctx<'_>) -> Result<()> {
    let mut v = value;
    for key in path {
        match v.get(*key) {
            Some(next) => v = next,
            None => return Ok(()),
        }
    }
    match v.as_u64() {
        Some(n) if n <= u64::from(u32::MAX) => Ok(()),
        Some(n) => Err(ctx.err(
            element,
            format!("`{}` is {n}, larger than any valid index", path.join(".")),
        )),
        // Not an unsigned integer: the typed deserialization reports it.
        None => Ok(()),
    }
}

fn check_version(root: &Map<String, Value>, ctx: &Ctx<'_>) -> Result<()> {
    const V1: &str = "glTF 1.0 is not supported (only glTF 2.0); convert the file to glTF 2.0";
    let Some(asset) = root.get("asset") else {
        // glTF 1.0 keyed its top-level collections by id, as objects.
        let v1 = ["meshes", "nodes", "buffers", "accessors"]
            .iter()
            .any(|k| root.get(*k).is_some_and(Value::is_object));
        return Err(if v1 {
            ctx.err(
                "asset",
                format!("missing, and the collections are objects: {V1}"),
            )
        } else {
            ctx.err(
                "asset",
                "missing (glTF 2.0 requires `asset` with `version`)",
            )
        });
    };
    let version = match asset.get("version") {
        Some(Value::String(s)) => s.clone(),
        Some(Value::Number(n)) => n.to_string(),
        Some(other) => return Err(ctx.err("asset.version", format!("is not a string: {other}"))),
        None => return Err(ctx.err("asset.version", "missing (glTF 2.0 requires it)")),
    };
    let major = version.split('.').next().unwrap_or_default().trim();
    match major {
        "2" => {}
        "0" | "1" => return Err(ctx.err("asset.version", format!("is \"{version}\": {V1}"))),
        _ => {
            return Err(ctx.err(
                "asset.version",
                format!("is \"{version}\": unsupported glTF version (only 2.x is supported)"),
            ))
        }
    }
    if let Some(min) = asset.get("minVersion").and_then(Value::as_str) {
        let min_major = min.split('.').next().unwrap_or_default();
        let min_minor = min.split('.').nth(1).unwrap_or("0");
        if min_major != "2" || min_minor != "0" {
            return Err(ctx.err(
                "asset.minVersion",
                format!("is \"{min}\": the file needs a newer glTF reader than 2.0"),
            ));
        }
    }
    Ok(())
}

fn string_list(root: &Map<String, Value>, key: &str, ctx: &Ctx<'_>) -> Result<Vec<String>> {
    match root.get(key) {
        None | Some(Value::Null) => Ok(Vec::new()),
        Some(Value::Array(items)) => items
            .iter()
            .map(|v| {
                v.as_str()
                    .map(str::to_string)
                    .ok_or_else(|| ctx.err(key, format!("contains {v}, which is not a string")))
            })
            .collect(),
        Some(other) => Err(ctx.err(key, format!("is not an array: {other}"))),
    }
}
