//! The bench scenes: the procedural city and the box cities of the shared corpus.

use scene::load::Loaded;
use scene::procedural::city::{city, CityParams};
use scene::{CameraPath, Light, LookAt, Scene};
use std::sync::Arc;

/// A bench scene: what its source defines (cameras, camera paths, lights)
/// beside the flattened scene.
pub struct BenchScene {
    /// The loaded source (its graph is the one `scene` was built from).
    pub loaded: Loaded,
    /// The flattened scene.
    pub scene: Arc<Scene>,
}

impl BenchScene {
    /// Flattens a loaded source.
    ///
    /// # Panics
    /// When the scene cannot be built.
    pub fn new(loaded: Loaded) -> Self {
        let scene = Scene::new(loaded.graph.clone()).expect("a flattened scene");
        BenchScene {
            loaded,
            scene: Arc::new(scene),
        }
    }

    /// The procedural city with `params`.
    ///
    /// # Panics
    /// When the parameters are invalid.
    pub fn city(params: &CityParams) -> Self {
        Self::new(city(params).expect("a procedural city"))
    }

    /// The default procedural city (`CityParams::default()`, 20 × 20 blocks).
    pub fn default_city() -> Self {
        Self::city(&CityParams::default())
    }

    /// The procedural city of `blocks × blocks` blocks, other parameters default.
    pub fn city_blocks(blocks: u32) -> Self {
        Self::city(&CityParams {
            blocks_x: blocks,
            blocks_z: blocks,
            ..Default::default()
        })
    }

    /// The box city `../shared/data/bench/<name>.txt` (`city_4096`,
    /// `city_16384`), or `None` with a printed note when it is absent.
    ///
    /// # Panics
    /// When the file is there but does not load.
    pub fn box_city(name: &str) -> Option<Self> {
        let file = crate::shared_file(&format!("bench/{name}.txt"))?;
        let loaded = scene::load::box_city::load_box_city(&file)
            .unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        Some(Self::new(loaded))
    }

    /// The camera path called `name`.
    ///
    /// # Panics
    /// When the source has no such path.
    pub fn path(&self, name: &str) -> &CameraPath {
        self.loaded
            .paths
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, p)| p)
            .unwrap_or_else(|| panic!("no camera path {name:?}"))
    }

    /// The camera pose called `name`.
    ///
    /// # Panics
    /// When the source has no such camera.
    pub fn look(&self, name: &str) -> &LookAt {
        self.loaded
            .cameras
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, l)| l)
            .unwrap_or_else(|| panic!("no camera {name:?}"))
    }

    /// The source's first light (a box city's only one).
    ///
    /// # Panics
    /// When the source has no light.
    pub fn first_light(&self) -> Light {
        self.loaded.lights.first().expect("a light").1
    }
}

/// The procedural city of `blocks × blocks` blocks and its `street` camera
/// path: the culling tests' scene.
pub fn street_city(blocks: u32) -> (Arc<Scene>, CameraPath) {
    let city = BenchScene::city_blocks(blocks);
    let path = city.path("street").clone();
    (city.scene, path)
}
