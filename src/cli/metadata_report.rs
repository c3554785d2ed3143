//! The GIS metadata of a `.ezw` file as `info` shows it.

use serde::Serialize;
use wavemesh_codec::Metadata;

/// One free item, as `info --json` lists it.
#[derive(Serialize)]
pub struct ItemReport {
    name: String,
    value: String,
    /// GDAL metadata domain (empty: the default one).
    domain: String,
    /// A band item (GDAL `sample="0"`) rather than a dataset item.
    band: bool,
}

/// The metadata block: GDAL band scale/offset/description/unit type, CRS WKT, items.
#[derive(Serialize)]
pub struct MetadataReport {
    scale: Option<f64>,
    offset: Option<f64>,
    description: Option<String>,
    unit_type: Option<String>,
    crs_wkt: Option<String>,
    items: Vec<ItemReport>,
}

impl MetadataReport {
    /// The report of `metadata`.
    pub fn new(metadata: &Metadata) -> MetadataReport {
        MetadataReport {
            scale: metadata.scale,
            offset: metadata.offset,
            description: metadata.description.clone(),
            unit_type: metadata.unit_type.clone(),
            crs_wkt: metadata.crs_wkt.clone(),
            items: metadata
                .items
                .iter()
                .map(|i| ItemReport {
                    name: i.name.clone(),
                    value: i.value.clone(),
                    domain: i.domain.clone(),
                    band: i.band,
                })
                .collect(),
        }
    }

    /// Text lines for `info`, one per set field and item (none when empty).
    pub fn lines(&self) -> Vec<String> {
        let mut lines = Vec::new();
        let fields = [
            ("scale", self.scale.map(|v| v.to_string())),
            ("offset", self.offset.map(|v| v.to_string())),
            ("description", self.description.clone()),
            ("unit type", self.unit_type.clone()),
            ("CRS (WKT)", self.crs_wkt.clone()),
        ];
        for (name, value) in fields {
            if let Some(value) = value {
                lines.push(format!("  {name}: {value}"));
            }
        }
        for item in &self.items {
            let domain = match item.domain.as_str() {
                "" => String::new(),
                d => format!(" [{d}]"),
            };
            let band = if item.band { " (band)" } else { "" };
            lines.push(format!("  {}{domain}{band} = {}", item.name, item.value));
        }
        lines
    }
}
