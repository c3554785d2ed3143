//! GDAL's metadata XML to and from a raster's [`Metadata`]: the `GDAL_METADATA` TIFF tag
//! (42112) of a GeoTIFF, and the PAM `.aux.xml` side file GDAL reads beside a PNG.

use std::fmt::Write as _;

use wavemesh_codec::{Metadata, MetadataItem, Raster};

use super::DemError;

/// The TIFF tag GDAL keeps its metadata XML in.
pub(super) const GDAL_METADATA_TAG: u16 = 42112;

/// Parses a `GDAL_METADATA` document: band items (`sample="0"`) with a role become the
/// scale, offset, description and unit type; other items are kept as they are. Items of
/// other bands and XML-valued items are skipped.
pub(super) fn parse(xml: &str) -> Result<Metadata, DemError> {
    let doc = roxmltree::Document::parse(xml)
        .map_err(|e| DemError::Malformed(format!("GDAL_METADATA tag is not valid XML: {e}")))?;
    let mut metadata = Metadata::default();
    let items = doc
        .root_element()
        .children()
        .filter(|n| n.has_tag_name("Item"));
    for item in items {
        let sample = item.attribute("sample");
        if sample.is_some_and(|s| s != "0") || item.attribute("format") == Some("xml") {
            continue;
        }
        let value = unescape_value(item.text().unwrap_or(""));
        let number = || {
            value.trim().parse::<f64>().map_err(|_| {
                DemError::Malformed(format!("GDAL_METADATA holds a {} of '{value}'", role(item)))
            })
        };
        match (sample.is_some(), role(item)) {
            (true, "scale") => metadata.scale = Some(number()?),
            (true, "offset") => metadata.offset = Some(number()?),
            (true, "description") => metadata.description = Some(value),
            (true, "unittype") => metadata.unit_type = Some(value),
            (band, _) => metadata.items.push(MetadataItem {
                name: item.attribute("name").unwrap_or("").to_string(),
                value,
                domain: item.attribute("domain").unwrap_or("").to_string(),
                band,
            }),
        }
    }
    Ok(metadata)
}

/// GDAL escapes item values once more than XML needs (`&amp;amp;` for `&`) and unescapes
/// them after parsing: undo that second layer, keeping text another tool escaped once.
fn unescape_value(text: &str) -> String {
    roxmltree::Document::parse(&format!("<v>{text}</v>"))
        .ok()
        .and_then(|doc| doc.root_element().text().map(str::to_string))
        .unwrap_or_else(|| text.to_string())
}

fn role<'a>(item: roxmltree::Node<'a, '_>) -> &'a str {
    item.attribute("role").unwrap_or("")
}

/// The `GDAL_METADATA` document for `metadata`, `None` when there is nothing to write
/// (the CRS WKT goes elsewhere).
pub(super) fn to_tiff_xml(metadata: &Metadata) -> Option<String> {
    let mut xml = String::from("<GDALMetadata>\n");
    let mut any = false;
    for item in &metadata.items {
        any = true;
        let domain = match item.domain.as_str() {
            "" => String::new(),
            d => format!(" domain=\"{}\"", escape(d)),
        };
        let sample = if item.band { " sample=\"0\"" } else { "" };
        let _ = writeln!(
            xml,
            "  <Item name=\"{}\"{domain}{sample}>{}</Item>",
            escape(&item.name),
            escape(&escape(&item.value))
        );
    }
    for (name, role, value) in band_roles(metadata) {
        any = true;
        let _ = writeln!(
            xml,
            "  <Item name=\"{name}\" sample=\"0\" role=\"{role}\">{}</Item>",
            escape(&escape(&value))
        );
    }
    xml.push_str("</GDALMetadata>");
    any.then(|| ascii_only(&xml))
}

/// `xml` with every non-ASCII character as a character reference (`&#246;`): TIFF ASCII
/// tags hold 7-bit text.
fn ascii_only(xml: &str) -> String {
    let mut out = String::with_capacity(xml.len());
    for c in xml.chars() {
        if c.is_ascii() {
            out.push(c);
        } else {
            let _ = write!(out, "&#{};", u32::from(c));
        }
    }
    out
}

/// (item name, GDAL role, value) of the band's scale, offset, description and unit type.
fn band_roles(metadata: &Metadata) -> Vec<(&'static str, &'static str, String)> {
    [
        ("OFFSET", "offset", metadata.offset.map(|v| v.to_string())),
        ("SCALE", "scale", metadata.scale.map(|v| v.to_string())),
        ("DESCRIPTION", "description", metadata.description.clone()),
        ("UNITTYPE", "unittype", metadata.unit_type.clone()),
    ]
    .into_iter()
    .filter_map(|(name, role, value)| Some((name, role, value?)))
    .collect()
}

/// A GDAL PAM document (`.aux.xml`) for `raster`: its CRS (`srs`, WKT), geotransform,
/// dataset items, and the band's description, nodata, unit type, offset, scale and items.
pub(super) fn to_pam_xml(raster: &Raster, srs: Option<&str>) -> String {
    let metadata = &raster.metadata;
    let mut xml = String::from("<PAMDataset>\n");
    if let Some(srs) = srs {
        let _ = writeln!(xml, "  <SRS>{}</SRS>", escape(srs));
    }
    if let Some(g) = &raster.georef {
        let gt: Vec<String> = g.geotransform.iter().map(|v| v.to_string()).collect();
        let _ = writeln!(xml, "  <GeoTransform>{}</GeoTransform>", gt.join(", "));
    }
    write_pam_items(&mut xml, "  ", metadata.items.iter().filter(|i| !i.band));
    let band = pam_band(raster);
    if !band.is_empty() {
        let _ = write!(
            xml,
            "  <PAMRasterBand band=\"1\">\n{band}  </PAMRasterBand>\n"
        );
    }
    xml.push_str("</PAMDataset>\n");
    xml
}

/// The PAM elements of the band: description, nodata, unit type, offset, scale, items.
fn pam_band(raster: &Raster) -> String {
    let metadata = &raster.metadata;
    let mut xml = String::new();
    let nodata = raster.nodata.map(|v| {
        if v.is_nan() {
            "nan".to_string()
        } else {
            v.to_string()
        }
    });
    for (element, value) in [
        ("Description", metadata.description.clone()),
        ("NoDataValue", nodata),
        ("UnitType", metadata.unit_type.clone()),
        ("Offset", metadata.offset.map(|v| v.to_string())),
        ("Scale", metadata.scale.map(|v| v.to_string())),
    ] {
        if let Some(value) = value {
            let _ = writeln!(xml, "    <{element}>{}</{element}>", escape(&value));
        }
    }
    write_pam_items(&mut xml, "    ", metadata.items.iter().filter(|i| i.band));
    xml
}

/// PAM `<Metadata>` elements (one per domain) holding `items` as `<MDI>` entries.
fn write_pam_items<'a>(
    xml: &mut String,
    indent: &str,
    items: impl Iterator<Item = &'a MetadataItem>,
) {
    let mut domains: Vec<(&str, Vec<&MetadataItem>)> = Vec::new();
    for item in items {
        match domains.iter_mut().find(|(d, _)| *d == item.domain) {
            Some((_, list)) => list.push(item),
            None => domains.push((&item.domain, vec![item])),
        }
    }
    for (domain, list) in domains {
        let attr = match domain {
            "" => String::new(),
            d => format!(" domain=\"{}\"", escape(d)),
        };
        let _ = writeln!(xml, "{indent}<Metadata{attr}>");
        for item in list {
            let _ = writeln!(
                xml,
                "{indent}  <MDI key=\"{}\">{}</MDI>",
                escape(&item.name),
                escape(&item.value)
            );
        }
        let _ = writeln!(xml, "{indent}</Metadata>");
    }
}

/// Escapes text for an XML element or a double-quoted attribute.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const COPERNICUS: &str = r#"<GDALMetadata>
  <Item name="DTED_VerticalDatum">E08</Item>
  <Item name="AREA" domain="EXTRA">a &amp;lt;b&amp;gt; &amp;amp; &amp;quot;c&amp;quot;</Item>
  <Item name="OFFSET" sample="0" role="offset">100</Item>
  <Item name="SCALE" sample="0" role="scale">0.1</Item>
  <Item name="DESCRIPTION" sample="0" role="description">elevation</Item>
  <Item name="UNITTYPE" sample="0" role="unittype">m</Item>
  <Item name="STATISTICS_MEAN" sample="0">12.5</Item>
  <Item name="OTHER_BAND" sample="1">skipped</Item>
</GDALMetadata>"#;

    #[test]
    fn gdal_metadata_round_trips() {
        let m = parse(COPERNICUS).unwrap();
        assert_eq!((m.scale, m.offset), (Some(0.1), Some(100.0)));
        assert_eq!(m.description.as_deref(), Some("elevation"));
        assert_eq!(m.unit_type.as_deref(), Some("m"));
        assert_eq!(m.items.len(), 3);
        assert_eq!(m.items[0].value, "E08");
        assert_eq!(
            (m.items[1].domain.as_str(), m.items[1].value.as_str()),
            ("EXTRA", "a <b> & \"c\"")
        );
        assert!(m.items[2].band);
        assert_eq!(parse(&to_tiff_xml(&m).unwrap()).unwrap(), m);
        assert_eq!(to_tiff_xml(&Metadata::default()), None);
    }

    #[test]
    fn bad_metadata_is_a_clear_error() {
        assert!(parse("<GDALMetadata><Item").is_err());
        let bad_scale =
            r#"<GDALMetadata><Item name="SCALE" sample="0" role="scale">x</Item></GDALMetadata>"#;
        let e = parse(bad_scale).unwrap_err().to_string();
        assert!(e.contains("scale of 'x'"), "{e}");
    }
}
