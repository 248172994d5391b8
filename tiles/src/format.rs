//! What a tile's bytes are: [`TileFormat`] from MBTiles' `format` or from the bytes themselves,
//! and the HTTP headers that serve them as stored.

/// A tile's encoding.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TileFormat {
    /// PNG raster.
    Png,
    /// JPEG raster.
    Jpeg,
    /// WebP raster.
    Webp,
    /// Mapbox Vector Tile (protocol buffers), usually gzip-compressed in MBTiles.
    Pbf,
}

impl TileFormat {
    /// MBTiles' `format` metadata value: `png`, `jpg` (or `jpeg`), `webp`, `pbf`.
    pub fn from_metadata(s: &str) -> Option<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "png" => Some(Self::Png),
            "jpg" | "jpeg" => Some(Self::Jpeg),
            "webp" => Some(Self::Webp),
            "pbf" | "mvt" => Some(Self::Pbf),
            _ => None,
        }
    }

    /// The raster format the bytes start with (PNG, JPEG or WebP signature); `None` for
    /// anything else (vector tiles have no signature).
    pub fn sniff(data: &[u8]) -> Option<Self> {
        if data.starts_with(b"\x89PNG\r\n\x1a\n") {
            Some(Self::Png)
        } else if data.starts_with(&[0xff, 0xd8, 0xff]) {
            Some(Self::Jpeg)
        } else if data.len() >= 12 && &data[..4] == b"RIFF" && &data[8..12] == b"WEBP" {
            Some(Self::Webp)
        } else {
            None
        }
    }

    /// Its name in MBTiles' metadata.
    pub fn name(self) -> &'static str {
        match self {
            Self::Png => "png",
            Self::Jpeg => "jpg",
            Self::Webp => "webp",
            Self::Pbf => "pbf",
        }
    }

    /// Its media type (`Content-Type`).
    pub fn content_type(self) -> &'static str {
        match self {
            Self::Png => "image/png",
            Self::Jpeg => "image/jpeg",
            Self::Webp => "image/webp",
            Self::Pbf => "application/vnd.mapbox-vector-tile",
        }
    }

    /// A raster format a browser draws as an image.
    pub fn is_raster(self) -> bool {
        self != Self::Pbf
    }
}

/// The bytes are gzip-compressed (served with `Content-Encoding: gzip`, as stored).
pub fn is_gzip(data: &[u8]) -> bool {
    data.starts_with(&[0x1f, 0x8b])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_come_from_the_metadata_or_the_signature() {
        assert_eq!(TileFormat::from_metadata("PNG"), Some(TileFormat::Png));
        assert_eq!(TileFormat::from_metadata("jpeg"), Some(TileFormat::Jpeg));
        assert_eq!(TileFormat::from_metadata("pbf"), Some(TileFormat::Pbf));
        assert_eq!(TileFormat::from_metadata("tiff"), None);
        assert_eq!(
            TileFormat::sniff(b"\x89PNG\r\n\x1a\n...."),
            Some(TileFormat::Png)
        );
        assert_eq!(
            TileFormat::sniff(&[0xff, 0xd8, 0xff, 0xe0]),
            Some(TileFormat::Jpeg)
        );
        assert_eq!(
            TileFormat::sniff(b"RIFF\0\0\0\0WEBPVP8 "),
            Some(TileFormat::Webp)
        );
        assert_eq!(TileFormat::sniff(&[0x1f, 0x8b, 8, 0]), None);
        assert!(is_gzip(&[0x1f, 0x8b, 8, 0]) && !is_gzip(b"\x1a\x02"));
        assert_eq!(
            TileFormat::Pbf.content_type(),
            "application/vnd.mapbox-vector-tile"
        );
    }
}
