//! `[map]`: where the dashboard's geographic map gets its tiles — an MBTiles file the service
//! serves at `/tiles/{z}/{x}/{y}` (offline), a tile URL template (online), or both (the page
//! offers both, the URL first) — and what it credits.

use serde::{Deserialize, Serialize};

use super::error::ConfigError;

/// The attribution OpenStreetMap's tiles require (its tile usage policy).
pub const OSM_ATTRIBUTION: &str = "© OpenStreetMap contributors";

/// `[map]`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct MapConfig {
    /// An MBTiles file (raster PNG/JPEG/WebP or vector pbf tiles), opened read-only at start
    /// and served at `/tiles/{z}/{x}/{y}`; a file that is missing or not MBTiles stops the start
    /// with an error naming it. Empty: none (`harrier demo` generates one of its world).
    pub mbtiles: String,
    /// A tile URL template with `{z}`, `{x}`, `{y}` (and optionally `{s}` for `a`, `b`, `c`
    /// subdomains, `{r}` for `@2x`), e.g. `https://tile.openstreetmap.org/{z}/{x}/{y}.png`,
    /// fetched by the browser. Empty: none.
    pub tile_url: String,
    /// What the page credits for `tile_url`'s tiles (text). Empty: "© OpenStreetMap
    /// contributors" for an openstreetmap.org URL, else nothing (set it: most tile services
    /// require one). The MBTiles file's tiles are credited with its own `attribution`.
    pub attribution: String,
    /// Lowest zoom level of `tile_url` (0–24).
    pub min_zoom: u8,
    /// Highest zoom level `tile_url` has tiles for (0–24); the page scales them beyond.
    pub max_zoom: u8,
}

impl Default for MapConfig {
    /// No tiles; a tile URL's zoom levels OpenStreetMap's 0–19.
    fn default() -> Self {
        Self {
            mbtiles: String::new(),
            tile_url: String::new(),
            attribution: String::new(),
            min_zoom: 0,
            max_zoom: 19,
        }
    }
}

impl MapConfig {
    /// The attribution of `tile_url`: `attribution`, else OpenStreetMap's for its URLs.
    pub fn url_attribution(&self) -> Option<String> {
        if !self.attribution.is_empty() {
            Some(self.attribution.clone())
        } else if self.tile_url.contains("openstreetmap.org") {
            Some(OSM_ATTRIBUTION.into())
        } else {
            None
        }
    }

    /// The checks a TOML parser cannot make.
    pub(super) fn check(&self) -> Result<(), ConfigError> {
        let bad = |m: String| Err(ConfigError::Invalid(format!("map.{m}")));
        if !self.tile_url.is_empty() {
            let u = &self.tile_url;
            if !(u.starts_with("http://") || u.starts_with("https://") || u.starts_with('/')) {
                return bad(format!(
                    "tile_url {u:?}: expected an http:// or https:// URL (or a path on this server)"
                ));
            }
            if let Some(missing) = ["{z}", "{x}", "{y}"].into_iter().find(|p| !u.contains(p)) {
                return bad(format!("tile_url {u:?} has no {missing}"));
            }
        }
        if self.min_zoom > self.max_zoom || self.max_zoom > 24 {
            return bad(format!(
                "min_zoom {} and max_zoom {}: expected min ≤ max ≤ 24",
                self.min_zoom, self.max_zoom
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(text: &str) -> Result<MapConfig, String> {
        let c: MapConfig = toml::from_str(text).map_err(|e| e.to_string())?;
        c.check().map_err(|e| e.to_string())?;
        Ok(c)
    }

    #[test]
    fn a_tile_url_needs_its_placeholders_and_osm_is_credited_by_default() {
        let osm = map("tile_url = \"https://tile.openstreetmap.org/{z}/{x}/{y}.png\"").expect("ok");
        assert_eq!(osm.url_attribution().as_deref(), Some(OSM_ATTRIBUTION));
        let own =
            map("tile_url = \"http://127.0.0.1:9000/{z}/{x}/{y}.png\"\nattribution = \"© us\"")
                .expect("ok");
        assert_eq!(own.url_attribution().as_deref(), Some("© us"));
        let e = map("tile_url = \"http://h/{z}/{x}.png\"").expect_err("no y");
        assert!(e.contains("has no {y}"), "{e}");
        let e = map("tile_url = \"ftp://h/{z}/{x}/{y}\"").expect_err("scheme");
        assert!(e.contains("http://"), "{e}");
        let e = map("min_zoom = 5\nmax_zoom = 3").expect_err("range");
        assert!(e.contains("min_zoom 5"), "{e}");
        assert!(map("bogus = 1").is_err());
    }
}
