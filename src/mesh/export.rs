//! Mesh files: binary glTF 2.0 (`.glb`), Wavefront OBJ (`.obj`) and binary PLY (`.ply`).
//!
//! [`encode_mesh`] turns a [`GridMesh`] and the heights of its grid into the bytes of a
//! file; [`write_mesh`] writes them atomically. A [`Placement`] says where each grid
//! sample goes: pixel units (`x` = column, `y` = row), the raster's geotransform (the
//! pixel centre, in the CRS's units) or, for geographic DEMs, metres east, north and up
//! of the DEM's centre ([`Placement::metric`], [`super::frame`]); heights are multiplied
//! by `z_scale`. Every file records its frame: the glb in its node's `extras.wavemesh`
//! (frame name, CRS, `z_scale`, the local frame's origin), OBJ and PLY in a header
//! comment.
//!
//! Every output triangle is counter-clockwise seen from above (+z in OBJ and PLY, +Y in
//! glTF), so its normal points up: when the placement mirrors the grid (a north-up
//! geotransform, whose row step is negative, does) the exporter swaps two corners of every
//! triangle.
//!
//! Frames and precision:
//! - OBJ and PLY keep the terrain frame (x east, y north, z up) with `f64` coordinates
//!   (OBJ prints each with the shortest text that reads back to the same `f64`), so UTM
//!   coordinates stay exact.
//! - glTF is Y-up: a terrain point (x, y, z) is stored as `(x − cx, z, −(y − cy))` in
//!   `f32`, where (cx, cy) is the centre of the vertices' x/y bounding box, and the mesh's
//!   node gets the translation `[cx, 0, −cy]`. The mapping is a rotation, so faces stay
//!   front-facing, and the `f32` positions stay precise however large the coordinates.
//!   The glb has one matte material (metallic 0, roughness 0.9).
//!
//! Empty meshes: a mesh without triangles still gives valid files. OBJ and PLY hold its
//! vertices and no faces. glTF forbids empty accessors and buffers, so its `.glb` holds a
//! scene with one node, named `terrain`, that has no mesh, and no binary chunk.

use std::fmt::Write as _;
use std::io;
use std::path::Path;

use serde_json::{json, Value};

use wavemesh_codec::Georef;

use super::frame::{FrameError, HorizontalCrs, LocalFrame};
use super::GridMesh;
use crate::atomic::write_atomic;

/// Mesh file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MeshFormat {
    /// Binary glTF 2.0 (`.glb`).
    Glb,
    /// Wavefront OBJ text (`.obj`).
    Obj,
    /// Binary little-endian PLY (`.ply`).
    Ply,
}

impl MeshFormat {
    /// From the output path's extension (`.glb`, `.obj`, `.ply`; case-insensitive); `None`
    /// otherwise.
    pub fn from_path(path: &Path) -> Option<MeshFormat> {
        let ext = path.extension()?.to_str()?;
        if ext.eq_ignore_ascii_case("glb") {
            Some(MeshFormat::Glb)
        } else if ext.eq_ignore_ascii_case("obj") {
            Some(MeshFormat::Obj)
        } else if ext.eq_ignore_ascii_case("ply") {
            Some(MeshFormat::Ply)
        } else {
            None
        }
    }

    /// Short lower-case name, also the file extension (`glb`, `obj`, `ply`).
    pub fn name(self) -> &'static str {
        match self {
            MeshFormat::Glb => "glb",
            MeshFormat::Obj => "obj",
            MeshFormat::Ply => "ply",
        }
    }
}

/// How grid vertices become coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum XyUnits {
    /// Through the raster's geotransform, at pixel centres, in the CRS's own units (pixel
    /// units without a geotransform).
    #[default]
    Georeferenced,
    /// Column and row numbers.
    Pixel,
    /// Metres east, north and up in a tangent frame: the geotransform gives longitude and
    /// latitude in degrees (geographic DEMs).
    Local(LocalFrame),
    /// Metres east and north in the tangent plane of a frame, to first order at its
    /// origin ([`LocalFrame::tangent`]: an affine map of longitude and latitude), and z
    /// the stored value × z_scale (the ground does not curve away): the frame of views,
    /// whose selection needs an affine grid.
    Tangent(LocalFrame),
}

/// Where grid samples go in the output file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// Geotransform used unless `xy` is [`XyUnits::Pixel`] (`None` → pixel units are used,
    /// and [`Placement::frame_name`] says `pixel`).
    pub geotransform: Option<[f64; 6]>,
    /// Pixel, georeferenced or local metric x/y.
    pub xy: XyUnits,
    /// Multiplies heights (default 1).
    pub z_scale: f64,
    /// The DEM's horizontal CRS, recorded in the file.
    pub crs: HorizontalCrs,
}

impl Default for Placement {
    /// Georeferenced x/y without a geotransform (so pixel units) and `z_scale` 1.
    fn default() -> Self {
        Placement {
            geotransform: None,
            xy: XyUnits::Georeferenced,
            z_scale: 1.0,
            crs: HorizontalCrs::Unknown,
        }
    }
}

impl Placement {
    /// Pixel units with heights multiplied by `z_scale`.
    pub fn pixel(z_scale: f64) -> Placement {
        Placement {
            xy: XyUnits::Pixel,
            z_scale,
            ..Placement::default()
        }
    }

    /// Georeferenced through `geotransform` with heights multiplied by `z_scale`.
    pub fn georeferenced(geotransform: [f64; 6], z_scale: f64) -> Placement {
        Placement {
            geotransform: Some(geotransform),
            z_scale,
            ..Placement::default()
        }
    }

    /// The CRS's own x/y (degrees for a geographic DEM), with the CRS recorded; pixel
    /// units without georeferencing.
    pub fn crs_units(georef: Option<&Georef>, z_scale: f64) -> Placement {
        match georef {
            Some(g) => Placement {
                crs: HorizontalCrs::of(g).unwrap_or_default(),
                ..Placement::georeferenced(g.geotransform, z_scale)
            },
            None => Placement {
                z_scale,
                ..Placement::default()
            },
        }
    }

    /// The default placement of a `width × height` raster with `georef`: a geographic
    /// DEM goes to the east-north-up frame at its centre (metres), any other keeps its
    /// CRS's own x/y ([`Placement::crs_units`]).
    pub fn metric(
        georef: Option<&Georef>,
        width: usize,
        height: usize,
        z_scale: f64,
    ) -> Result<Placement, FrameError> {
        let Some(g) = georef else {
            return Ok(Placement::crs_units(None, z_scale));
        };
        let crs = HorizontalCrs::of(g)?;
        let HorizontalCrs::Geographic {
            degrees_per_unit, ..
        } = crs
        else {
            return Ok(Placement::crs_units(georef, z_scale));
        };
        let degrees = g.geotransform.map(|v| v * degrees_per_unit);
        Ok(Placement {
            geotransform: Some(degrees),
            xy: XyUnits::Local(LocalFrame::of_grid(&degrees, width, height)?),
            z_scale,
            crs,
        })
    }

    /// The placement of a view of a `width × height` raster with `georef`: a geographic
    /// DEM goes to the tangent plane at its centre (metres, [`XyUnits::Tangent`]), any
    /// other keeps its CRS's own x/y ([`Placement::crs_units`]).
    pub fn tangent(
        georef: Option<&Georef>,
        width: usize,
        height: usize,
        z_scale: f64,
    ) -> Result<Placement, FrameError> {
        let metric = Placement::metric(georef, width, height, z_scale)?;
        Ok(match metric.xy {
            XyUnits::Local(frame) => Placement {
                xy: XyUnits::Tangent(frame),
                ..metric
            },
            _ => metric,
        })
    }

    /// The geotransform in use: `None` for pixel units.
    fn active_geotransform(&self) -> Option<&[f64; 6]> {
        match self.xy {
            XyUnits::Pixel => None,
            _ => self.geotransform.as_ref(),
        }
    }

    /// (x, y, z) of the sample at (`col`, `row`) with stored height `h`.
    ///
    /// Pixel units: `(col, row, h · z_scale)`. Georeferenced: the pixel centre,
    /// `x = gt0 + (col + ½)·gt1 + (row + ½)·gt2`, `y = gt3 + (col + ½)·gt4 + (row + ½)·gt5`,
    /// `z = h · z_scale`. Local: that (x, y) as longitude and latitude, `z` as height,
    /// taken to east, north and up of the frame's origin.
    pub fn position(&self, col: usize, row: usize, h: f64) -> [f64; 3] {
        let z = h * self.z_scale;
        let Some(gt) = self.active_geotransform() else {
            return [col as f64, row as f64, z];
        };
        let c = col as f64 + 0.5;
        let r = row as f64 + 0.5;
        let x = gt[0] + c * gt[1] + r * gt[2];
        let y = gt[3] + c * gt[4] + r * gt[5];
        match self.xy {
            XyUnits::Local(frame) => frame.enu(x, y, z),
            XyUnits::Tangent(frame) => {
                let [east, north] = frame.tangent(x, y);
                [east, north, z]
            }
            _ => [x, y, z],
        }
    }

    /// Whether the mapping (column, row) → (x, y) mirrors the plane (the determinant of
    /// the geotransform's 2×2 part is negative, as for every north-up raster, whose row
    /// step `gt5` is negative). The exporter then swaps two corners of every triangle so
    /// that every output triangle is counter-clockwise seen from +z (its normal points up)
    /// in the output frame. The local frame keeps the orientation of longitude and
    /// latitude (east and north are positive multiples of them near the origin).
    ///
    /// The sign of `z_scale` plays no part: scaling z does not move the x/y projection of a
    /// triangle, so it cannot change which way the triangle turns seen from above.
    pub fn flips_winding(&self) -> bool {
        match self.active_geotransform() {
            None => false,
            Some(gt) => gt[1] * gt[5] - gt[2] * gt[4] < 0.0,
        }
    }

    /// The name of the output frame: `pixel`, `georeferenced` (the CRS's own x/y),
    /// `local_enu` (metres east, north, up) or `local_tangent` (metres east and north in
    /// the tangent plane, heights up).
    pub fn frame_name(&self) -> &'static str {
        match (self.xy, self.active_geotransform()) {
            (_, None) => "pixel",
            (XyUnits::Local(_), Some(_)) => "local_enu",
            (XyUnits::Tangent(_), Some(_)) => "local_tangent",
            (_, Some(_)) => "georeferenced",
        }
    }

    /// The origin of a local frame in use.
    fn local_frame(&self) -> Option<LocalFrame> {
        match (self.xy, self.active_geotransform()) {
            (XyUnits::Local(f) | XyUnits::Tangent(f), Some(_)) => Some(f),
            _ => None,
        }
    }

    /// What a file records about its frame: its name, the CRS, the units, `z_scale` and,
    /// for the local frame, its origin on WGS 84.
    pub fn frame_record(&self) -> Value {
        let mut record = json!({
            "frame": self.frame_name(),
            "crs": self.crs.label(),
            "z_scale": self.z_scale,
        });
        if let Some(f) = self.local_frame() {
            record["units"] = json!("metre");
            record["origin"] = json!({
                "longitude": f.lon,
                "latitude": f.lat,
                "height": f.height,
                "ellipsoid": "WGS 84",
            });
        }
        record
    }

    /// One line of ASCII describing the frame, for the OBJ and PLY headers.
    pub fn frame_text(&self) -> String {
        let z = format!("z = stored value * {}", self.z_scale);
        let crs = self.crs.label();
        match (self.xy, self.active_geotransform()) {
            (_, None) => format!("frame pixel: x = column, y = row, {z}"),
            (XyUnits::Local(f), Some(_)) => format!(
                "frame local_enu: metres east (x), north (y) and up (z) of longitude {} latitude {} height {} on WGS 84; CRS {crs}; {z}",
                f.lon, f.lat, f.height
            ),
            (XyUnits::Tangent(f), Some(_)) => format!(
                "frame local_tangent: metres east (x) and north (y) in the tangent plane at longitude {} latitude {} on WGS 84, to first order; CRS {crs}; {z}",
                f.lon, f.lat
            ),
            (_, Some(_)) => {
                format!("frame georeferenced: x/y in the units of CRS {crs} (pixel centres); {z}")
            }
        }
    }
}

/// Why a mesh could not be exported.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The grid's sample count overflows.
    #[error("grid of {width} × {height} samples is too large")]
    GridTooLarge {
        /// Samples per row.
        width: usize,
        /// Rows.
        height: usize,
    },
    /// A vertex names a sample outside the grid.
    #[error("vertex {vertex} is sample {sample}, outside the {width} × {height} grid")]
    VertexOutsideGrid {
        /// The vertex.
        vertex: usize,
        /// Its sample index.
        sample: u32,
        /// Samples per row.
        width: usize,
        /// Rows.
        height: usize,
    },
    /// A vertex's sample has no height.
    #[error("vertex {vertex} is sample {sample}, but only {heights} heights were given")]
    MissingHeight {
        /// The vertex.
        vertex: usize,
        /// Its sample index.
        sample: u32,
        /// Number of heights given.
        heights: usize,
    },
    /// A vertex's height is NaN or infinite.
    #[error("sample {sample} has a non-finite height ({height})")]
    NonFiniteHeight {
        /// The sample index.
        sample: u32,
        /// The height.
        height: f64,
    },
    /// A vertex's position is NaN or infinite (a non-finite geotransform or `z_scale`, or
    /// an overflow), or does not fit the format's number type (`f32` for glb).
    #[error("vertex {vertex} lands at {position:?}, which a {format} file cannot hold")]
    NonFinitePosition {
        /// The vertex.
        vertex: usize,
        /// Its position in the terrain frame.
        position: [f64; 3],
        /// The format.
        format: &'static str,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error("triangle {triangle} refers to vertex {index}, but there are {vertices} vertices")]
    BadTriangle {
        /// The triangle.
        triangle: usize,
        /// The offending vertex index.
        index: u32,
        /// Number of vertices.
        vertices: usize,
    },
    /// More vertices than the format's index type can address.
    #[error("{vertices} vertices are too many for {format} (at most {max})")]
    TooManyVertices {
        /// Number of vertices.
        vertices: usize,
        /// Largest number the format allows.
        max: u64,
        /// The format.
        format: &'static str,
    },
    /// The file would exceed the format's size limit (4 GiB for `.glb`) or the memory
    /// available.
    #[error("the {format} file would be too large")]
    TooLarge {
        /// The format.
        format: &'static str,
    },
    /// Writing the file failed.
    #[error("cannot write the mesh file: {0}")]
    Io(#[from] io::Error),
}

/// Encodes `mesh` with heights `heights[sample_index]` (one per grid sample; only the
/// vertices' samples are read) as `format`.
pub fn encode_mesh(
    mesh: &GridMesh,
    heights: &[f64],
    placement: &Placement,
    format: MeshFormat,
) -> Result<Vec<u8>, ExportError> {
    let name = format.name();
    let positions = positions(mesh, heights, placement, name)?;
    let triangles = oriented_triangles(mesh, placement, name)?;
    match format {
        MeshFormat::Glb => encode_glb(&positions, &triangles, placement.frame_record(), None),
        MeshFormat::Obj => Ok(encode_obj(&positions, &triangles, &placement.frame_text())),
        MeshFormat::Ply => encode_ply(&positions, &triangles, &placement.frame_text()),
    }
}

/// Encodes the mesh as [`encode_mesh`] does and writes it to `path` atomically (readers
/// see the old file or the complete new one).
pub fn write_mesh(
    path: &Path,
    mesh: &GridMesh,
    heights: &[f64],
    placement: &Placement,
    format: MeshFormat,
) -> Result<(), ExportError> {
    let bytes = encode_mesh(mesh, heights, placement, format)?;
    write_atomic(path, |w| w.write_all(&bytes))?;
    Ok(())
}

/// Binary glTF of a mesh whose vertices are already placed (`positions`: `[x, y, z]` in
/// `placement`'s frame, flattened; `triangles` counter-clockwise in the grid frame), with
/// x/y stored relative to `centre` instead of the mesh's own centre: pieces of one DEM
/// written with one centre have bit-identical coordinates where they meet.
pub fn encode_glb_about(
    positions: &[f64],
    triangles: &[[u32; 3]],
    placement: &Placement,
    centre: [f64; 2],
) -> Result<Vec<u8>, ExportError> {
    let flip = placement.flips_winding();
    let oriented: Vec<[u32; 3]> = triangles
        .iter()
        .map(|t| if flip { [t[0], t[2], t[1]] } else { *t })
        .collect();
    encode_glb(positions, &oriented, placement.frame_record(), Some(centre))
}

/// The mesh as the files hold it, for callers that want arrays instead of a file (the
/// Python package): every vertex's `[x, y, z]` flattened and every triangle's vertex
/// indices, counter-clockwise seen from +z in `placement`'s frame.
pub fn placed_mesh(
    mesh: &GridMesh,
    heights: &[f64],
    placement: &Placement,
) -> Result<(Vec<f64>, Vec<[u32; 3]>), ExportError> {
    let positions = positions(mesh, heights, placement, "array")?;
    Ok((positions, oriented_triangles(mesh, placement, "array")?))
}

/// Terrain-frame positions of every vertex, `[x, y, z]` flattened (`format` names the
/// output in errors).
fn positions(
    mesh: &GridMesh,
    heights: &[f64],
    placement: &Placement,
    format: &'static str,
) -> Result<Vec<f64>, ExportError> {
    let samples = mesh
        .width
        .checked_mul(mesh.height)
        .ok_or(ExportError::GridTooLarge {
            width: mesh.width,
            height: mesh.height,
        })?;
    let mut out = Vec::new();
    out.try_reserve_exact(mesh.vertices.len().saturating_mul(3))
        .map_err(|_| ExportError::TooLarge { format })?;
    for (vertex, &sample) in mesh.vertices.iter().enumerate() {
        let s = sample as usize;
        if s >= samples {
            return Err(ExportError::VertexOutsideGrid {
                vertex,
                sample,
                width: mesh.width,
                height: mesh.height,
            });
        }
        let h = *heights.get(s).ok_or(ExportError::MissingHeight {
            vertex,
            sample,
            heights: heights.len(),
        })?;
        if !h.is_finite() {
            return Err(ExportError::NonFiniteHeight { sample, height: h });
        }
        // `samples > 0` here, so `width > 0`.
        let p = placement.position(s % mesh.width, s / mesh.width, h);
        if !p.iter().all(|c| c.is_finite()) {
            return Err(ExportError::NonFinitePosition {
                vertex,
                position: p,
                format,
            });
        }
        out.extend_from_slice(&p);
    }
    Ok(out)
}

/// The triangles, checked against the vertex count and wound counter-clockwise in the
/// output frame.
fn oriented_triangles(
    mesh: &GridMesh,
    placement: &Placement,
    format: &'static str,
) -> Result<Vec<[u32; 3]>, ExportError> {
    let n = mesh.vertices.len();
    let flip = placement.flips_winding();
    let mut out = Vec::new();
    out.try_reserve_exact(mesh.triangles.len())
        .map_err(|_| ExportError::TooLarge { format })?;
    for (triangle, t) in mesh.triangles.iter().enumerate() {
        if let Some(&index) = t.iter().find(|&&i| i as usize >= n) {
            return Err(ExportError::BadTriangle {
                triangle,
                index,
                vertices: n,
            });
        }
        out.push(if flip { [t[0], t[2], t[1]] } else { *t });
    }
    Ok(out)
}

/// Number of vertices in a flattened position array.
fn vertex_count(positions: &[f64]) -> usize {
    positions.len() / 3
}

/// Wavefront OBJ text: header comments (counts, `frame`), `v x y z` lines, `f a b c`
/// lines (1-based).
fn encode_obj(positions: &[f64], triangles: &[[u32; 3]], frame: &str) -> Vec<u8> {
    let mut text = String::new();
    // Writing into a String cannot fail.
    let _ = writeln!(
        text,
        "# wavemesh terrain mesh: {} vertices, {} triangles",
        vertex_count(positions),
        triangles.len()
    );
    let _ = writeln!(text, "# {frame}");
    for p in positions.chunks_exact(3) {
        // `{}` prints the shortest text that reads back to the same f64.
        let _ = writeln!(text, "v {} {} {}", p[0], p[1], p[2]);
    }
    for t in triangles {
        let _ = writeln!(
            text,
            "f {} {} {}",
            u64::from(t[0]) + 1,
            u64::from(t[1]) + 1,
            u64::from(t[2]) + 1
        );
    }
    text.into_bytes()
}

/// Binary little-endian PLY: `double` x/y/z vertices, `uchar`-counted `uint` faces.
fn encode_ply(
    positions: &[f64],
    triangles: &[[u32; 3]],
    frame: &str,
) -> Result<Vec<u8>, ExportError> {
    let n = vertex_count(positions);
    // Indices are `uint`; every triangle index is already below `n`, but say so plainly.
    if n as u64 > u64::from(u32::MAX) + 1 {
        return Err(ExportError::TooManyVertices {
            vertices: n,
            max: u64::from(u32::MAX) + 1,
            format: "ply",
        });
    }
    let header = format!(
        "ply\n\
         format binary_little_endian 1.0\n\
         comment generated by wavemesh\n\
         comment {frame}\n\
         element vertex {n}\n\
         property double x\n\
         property double y\n\
         property double z\n\
         element face {}\n\
         property list uchar uint vertex_indices\n\
         end_header\n",
        triangles.len()
    );
    let size = n
        .checked_mul(24)
        .and_then(|v| {
            triangles
                .len()
                .checked_mul(13)
                .and_then(|f| f.checked_add(v))
        })
        .and_then(|b| b.checked_add(header.len()))
        .ok_or(ExportError::TooLarge { format: "ply" })?;
    let mut out = Vec::new();
    out.try_reserve_exact(size)
        .map_err(|_| ExportError::TooLarge { format: "ply" })?;
    out.extend_from_slice(header.as_bytes());
    for c in positions {
        out.extend_from_slice(&c.to_le_bytes());
    }
    for t in triangles {
        out.push(3);
        for &i in t {
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    Ok(out)
}

/// glTF component type of `f32`.
const GL_FLOAT: u32 = 5126;
/// glTF component type of `u16`.
const GL_UNSIGNED_SHORT: u32 = 5123;
/// glTF component type of `u32`.
const GL_UNSIGNED_INT: u32 = 5125;
/// glTF buffer view target of vertex attributes.
const GL_ARRAY_BUFFER: u32 = 34962;
/// glTF buffer view target of indices.
const GL_ELEMENT_ARRAY_BUFFER: u32 = 34963;
/// glTF primitive mode of triangle lists.
const GL_TRIANGLES: u32 = 4;

/// The glb's matte material: light grey, not metallic, rough (glTF's default material is
/// fully metallic, which renders every slope facing away from the light black).
fn matte_material() -> Value {
    json!({
        "name": "terrain",
        "pbrMetallicRoughness": {
            "baseColorFactor": [0.8, 0.8, 0.8, 1.0],
            "metallicFactor": 0.0,
            "roughnessFactor": 0.9,
        },
    })
}

/// The `terrain` node's `extras`: the frame record with the glTF axes spelled out.
fn node_extras(mut frame: Value) -> Value {
    frame["gltf_axes"] = json!("+X = x (east), +Y = z (up), -Z = y (north)");
    json!({ "wavemesh": frame })
}

/// Sizes and bounds of a glb's binary buffer.
struct GlbLayout {
    /// Vertex count.
    vertices: usize,
    /// Index count (3 per triangle).
    indices: usize,
    /// Whether indices are `u16` (else `u32`).
    short_indices: bool,
    /// Bytes of the positions, and of the normals.
    attribute_bytes: usize,
    /// Bytes of the indices.
    index_bytes: usize,
    /// Bytes of the whole buffer.
    bin_len: usize,
}

impl GlbLayout {
    /// The layout for `vertices` vertices and `triangles` triangles, checked against the
    /// container's `u32` lengths.
    fn new(vertices: usize, triangles: usize) -> Result<GlbLayout, ExportError> {
        const FORMAT: &str = "glb";
        let too_large = || ExportError::TooLarge { format: FORMAT };
        // An index may not be the largest value of its type (primitive restart).
        if vertices as u64 > u64::from(u32::MAX) {
            return Err(ExportError::TooManyVertices {
                vertices,
                max: u64::from(u32::MAX),
                format: FORMAT,
            });
        }
        let short_indices = vertices <= usize::from(u16::MAX);
        let index_size = if short_indices { 2 } else { 4 };
        let indices = triangles.checked_mul(3).ok_or_else(too_large)?;
        let attribute_bytes = vertices.checked_mul(12).ok_or_else(too_large)?;
        let index_bytes = indices.checked_mul(index_size).ok_or_else(too_large)?;
        let bin_len = attribute_bytes
            .checked_mul(2)
            .and_then(|a| a.checked_add(index_bytes))
            .filter(|&b| b <= u32::MAX as usize - (1 << 20))
            .ok_or_else(too_large)?;
        Ok(GlbLayout {
            vertices,
            indices,
            short_indices,
            attribute_bytes,
            index_bytes,
            bin_len,
        })
    }
}

/// Terrain-frame positions moved to glTF's Y-up frame around the centre of their x/y
/// bounding box: the centre, the moved positions and their `f32` bounds.
struct GltfPositions {
    /// Centre of the x/y bounding box (the node's translation).
    centre: [f64; 2],
    /// `(x − cx, z, −(y − cy))` per vertex, flattened.
    local: Vec<f64>,
    /// Smallest `f32` coordinate on each glTF axis.
    min: [f32; 3],
    /// Largest `f32` coordinate on each glTF axis.
    max: [f32; 3],
}

/// Moves `positions` to glTF's frame around `centre` (default: the centre of their x/y
/// bounding box), checking that everything fits an `f32`.
fn gltf_positions(
    positions: &[f64],
    centre: Option<[f64; 2]>,
) -> Result<GltfPositions, ExportError> {
    const FORMAT: &str = "glb";
    let centre = centre.unwrap_or_else(|| {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in positions.chunks_exact(3) {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        [mid(lo[0], hi[0]), mid(lo[1], hi[1])]
    });
    // Readers take the node translation as f32 too.
    if !centre.iter().all(|&c| (c as f32).is_finite()) {
        return Err(ExportError::NonFinitePosition {
            vertex: 0,
            position: [centre[0], centre[1], 0.0],
            format: FORMAT,
        });
    }
    let mut local = Vec::new();
    local
        .try_reserve_exact(positions.len())
        .map_err(|_| ExportError::TooLarge { format: FORMAT })?;
    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    for (vertex, p) in positions.chunks_exact(3).enumerate() {
        let q = [p[0] - centre[0], p[2], -(p[1] - centre[1])];
        for k in 0..3 {
            let f = q[k] as f32;
            if !f.is_finite() {
                return Err(ExportError::NonFinitePosition {
                    vertex,
                    position: [p[0], p[1], p[2]],
                    format: FORMAT,
                });
            }
            min[k] = min[k].min(f);
            max[k] = max[k].max(f);
        }
        local.extend_from_slice(&q);
    }
    Ok(GltfPositions {
        centre,
        local,
        min,
        max,
    })
}

/// Binary glTF 2.0 with one mesh of one indexed triangle primitive (POSITION, NORMAL)
/// and a matte material; `frame` goes into the node's `extras`; x/y are stored relative
/// to `centre` (default: the middle of the mesh).
fn encode_glb(
    positions: &[f64],
    triangles: &[[u32; 3]],
    frame: Value,
    centre: Option<[f64; 2]>,
) -> Result<Vec<u8>, ExportError> {
    if triangles.is_empty() {
        let doc = json!({
            "asset": { "version": "2.0", "generator": "wavemesh" },
            "scene": 0,
            "scenes": [{ "nodes": [0] }],
            "nodes": [{ "name": "terrain", "extras": node_extras(frame) }],
        });
        return glb_container(&doc, &[]);
    }
    let layout = GlbLayout::new(vertex_count(positions), triangles.len())?;
    let gltf = gltf_positions(positions, centre)?;
    let normals = vertex_normals(&gltf.local, triangles);

    let mut bin = Vec::new();
    bin.try_reserve_exact(layout.bin_len + 3)
        .map_err(|_| ExportError::TooLarge { format: "glb" })?;
    for &c in &gltf.local {
        bin.extend_from_slice(&(c as f32).to_le_bytes());
    }
    for &c in &normals {
        bin.extend_from_slice(&c.to_le_bytes());
    }
    for t in triangles {
        for &i in t {
            if layout.short_indices {
                // `i < n <= u16::MAX`, so the narrowing is exact.
                bin.extend_from_slice(&(i as u16).to_le_bytes());
            } else {
                bin.extend_from_slice(&i.to_le_bytes());
            }
        }
    }
    debug_assert_eq!(bin.len(), layout.bin_len);
    glb_container(&glb_document(&layout, &gltf, frame), &bin)
}

/// The glTF JSON of a glb laid out as `layout`.
fn glb_document(layout: &GlbLayout, gltf: &GltfPositions, frame: Value) -> Value {
    let translation: Vec<Value> = [gltf.centre[0], 0.0, -gltf.centre[1]]
        .iter()
        .map(|&v| json!(v))
        .collect();
    let attribute_bytes = layout.attribute_bytes;
    json!({
        "asset": { "version": "2.0", "generator": "wavemesh" },
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": [{
            "name": "terrain",
            "mesh": 0,
            "translation": translation,
            "extras": node_extras(frame),
        }],
        "meshes": [{
            "name": "terrain",
            "primitives": [{
                "attributes": { "POSITION": 0, "NORMAL": 1 },
                "indices": 2,
                "material": 0,
                "mode": GL_TRIANGLES,
            }],
        }],
        "materials": [matte_material()],
        "accessors": [
            {
                "bufferView": 0,
                "componentType": GL_FLOAT,
                "count": layout.vertices,
                "type": "VEC3",
                "min": gltf.min,
                "max": gltf.max,
            },
            {
                "bufferView": 1,
                "componentType": GL_FLOAT,
                "count": layout.vertices,
                "type": "VEC3",
            },
            {
                "bufferView": 2,
                "componentType": if layout.short_indices { GL_UNSIGNED_SHORT } else { GL_UNSIGNED_INT },
                "count": layout.indices,
                "type": "SCALAR",
            },
        ],
        "bufferViews": [
            {
                "buffer": 0,
                "byteOffset": 0,
                "byteLength": attribute_bytes,
                "target": GL_ARRAY_BUFFER,
            },
            {
                "buffer": 0,
                "byteOffset": attribute_bytes,
                "byteLength": attribute_bytes,
                "target": GL_ARRAY_BUFFER,
            },
            {
                "buffer": 0,
                "byteOffset": 2 * attribute_bytes,
                "byteLength": layout.index_bytes,
                "target": GL_ELEMENT_ARRAY_BUFFER,
            },
        ],
        "buffers": [{ "byteLength": layout.bin_len }],
    })
}

/// The midpoint of `[a, b]`, without overflowing.
fn mid(a: f64, b: f64) -> f64 {
    let m = a + (b - a) / 2.0;
    if m.is_finite() {
        m
    } else {
        a / 2.0 + b / 2.0
    }
}

/// Per-vertex normals (flattened `f32` xyz): the area-weighted average of the normals of
/// the triangles around each vertex, normalised; straight up (+Y) where that is undefined
/// (a vertex of no triangle or only of degenerate ones).
fn vertex_normals(local: &[f64], triangles: &[[u32; 3]]) -> Vec<f32> {
    let mut sum = vec![0.0f64; local.len()];
    let corner = |i: u32| {
        let i = i as usize * 3;
        [local[i], local[i + 1], local[i + 2]]
    };
    for t in triangles {
        let (a, b, c) = (corner(t[0]), corner(t[1]), corner(t[2]));
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        // Twice the area times the unit normal: summing weights by area.
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        for &i in t {
            let i = i as usize * 3;
            for k in 0..3 {
                sum[i + k] += n[k];
            }
        }
    }
    let mut out = Vec::with_capacity(sum.len());
    for s in sum.chunks_exact(3) {
        let len = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
        if len > 0.0 && len.is_finite() {
            out.extend(s.iter().map(|&c| (c / len) as f32));
        } else {
            out.extend_from_slice(&[0.0, 1.0, 0.0]);
        }
    }
    out
}

/// Wraps a glTF JSON document and its binary buffer in the GLB container: a 12-byte
/// header, a JSON chunk padded with spaces and, when `bin` is not empty, a BIN chunk
/// padded with zeros.
fn glb_container(doc: &Value, bin: &[u8]) -> Result<Vec<u8>, ExportError> {
    let too_large = || ExportError::TooLarge { format: "glb" };
    let mut json_bytes = doc.to_string().into_bytes();
    json_bytes.resize(json_bytes.len().next_multiple_of(4), b' ');
    let bin_padded = bin
        .len()
        .checked_next_multiple_of(4)
        .ok_or_else(too_large)?;
    let mut total = 12usize
        .checked_add(8)
        .and_then(|t| t.checked_add(json_bytes.len()))
        .ok_or_else(too_large)?;
    if !bin.is_empty() {
        total = total
            .checked_add(8)
            .and_then(|t| t.checked_add(bin_padded))
            .ok_or_else(too_large)?;
    }
    let total32 = u32::try_from(total).map_err(|_| too_large())?;
    let json_len = u32::try_from(json_bytes.len()).map_err(|_| too_large())?;
    let mut out = Vec::new();
    out.try_reserve_exact(total).map_err(|_| too_large())?;
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total32.to_le_bytes());
    out.extend_from_slice(&json_len.to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_bytes);
    if !bin.is_empty() {
        let bin_len = u32::try_from(bin_padded).map_err(|_| too_large())?;
        out.extend_from_slice(&bin_len.to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(bin);
        out.resize(total, 0);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const NORTH_UP: [f64; 6] = [500_000.0, 30.0, 0.0, 4_000_000.0, 0.0, -30.0];

    #[test]
    fn pixel_position_is_column_row_and_scaled_height() {
        let p = Placement::pixel(2.0);
        assert_eq!(p.position(0, 0, 0.0), [0.0, 0.0, 0.0]);
        assert_eq!(p.position(3, 7, 10.5), [3.0, 7.0, 21.0]);
        assert_eq!(p.frame_name(), "pixel");
    }

    #[test]
    fn georeferenced_position_is_pixel_centre() {
        let p = Placement::georeferenced(NORTH_UP, 1.0);
        assert_eq!(p.position(0, 0, 5.0), [500_015.0, 3_999_985.0, 5.0]);
        assert_eq!(p.position(2, 1, -1.0), [500_075.0, 3_999_955.0, -1.0]);
        // Rotated/sheared transforms use all six terms.
        let gt = [10.0, 2.0, 0.5, 20.0, 0.25, -3.0];
        let p = Placement::georeferenced(gt, 0.5);
        let [x, y, z] = p.position(1, 2, 8.0);
        assert_eq!(x, 10.0 + 1.5 * 2.0 + 2.5 * 0.5);
        assert_eq!(y, 20.0 + 1.5 * 0.25 + 2.5 * -3.0);
        assert_eq!(z, 4.0);
    }

    #[test]
    fn pixel_units_ignore_the_geotransform() {
        let p = Placement {
            geotransform: Some(NORTH_UP),
            xy: XyUnits::Pixel,
            ..Placement::default()
        };
        assert_eq!(p.position(4, 5, 1.0), [4.0, 5.0, 1.0]);
        assert!(!p.flips_winding());
        assert_eq!(p.frame_name(), "pixel");
    }

    /// A GeoKey directory with `GTModelTypeGeoKey` `model` and the CRS code `code`
    /// (geographic or projected as `model` says) and angular unit `unit`.
    fn georef(gt: [f64; 6], model: u16, code: u16, unit: u16) -> Georef {
        let crs_key = if model == 2 { 2048 } else { 3072 };
        Georef {
            geotransform: gt,
            geo_key_directory: vec![
                1, 1, 0, 3, 1024, 0, 1, model, crs_key, 0, 1, code, 2054, 0, 1, unit,
            ],
            ..Georef::default()
        }
    }

    /// Three arc-seconds, in degrees.
    const ARC3: f64 = 1.0 / 1200.0;

    #[test]
    fn geographic_dems_go_to_local_metres() {
        let gt = [-84.5, ARC3, 0.0, 36.8, 0.0, -ARC3];
        let g = georef(gt, 2, 4326, 9102);
        let p = Placement::metric(Some(&g), 401, 301, 1.0).unwrap();
        let XyUnits::Local(frame) = p.xy else {
            panic!("{p:?}")
        };
        assert_eq!(p.frame_name(), "local_enu");
        assert!((frame.lon - (-84.5 + 200.5 * ARC3)).abs() < 1e-12);
        // The centre sample is at the origin, its height straight up.
        let centre = p.position(200, 150, 500.0);
        assert!(centre
            .iter()
            .zip([0.0, 0.0, 500.0])
            .all(|(a, b)| (a - b).abs() < 1e-6));
        // One sample east is ~74.5 m at 36.7° N, one south ~92.5 m.
        let east = p.position(201, 150, 500.0);
        let south = p.position(200, 151, 500.0);
        assert!((74.0..75.0).contains(&(east[0] - centre[0])), "{east:?}");
        assert!(
            (-93.0..-92.0).contains(&(south[1] - centre[1])),
            "{south:?}"
        );
        assert!(p.flips_winding());
        let record = p.frame_record();
        assert_eq!(record["crs"], "EPSG:4326");
        assert_eq!(record["origin"]["ellipsoid"], "WGS 84");
        assert!(p.frame_text().contains("local_enu"));
        assert!(p.frame_text().is_ascii(), "PLY headers are ASCII");
        // The same in radians.
        let radians = georef(gt.map(f64::to_radians), 2, 4326, 9101);
        let q = Placement::metric(Some(&radians), 401, 301, 1.0).unwrap();
        let east_rad = q.position(201, 150, 500.0);
        assert!(east_rad.iter().zip(east).all(|(a, b)| (a - b).abs() < 1e-6));
    }

    #[test]
    fn projected_and_unreferenced_dems_keep_their_coordinates() {
        let g = georef(NORTH_UP, 1, 32632, 9102);
        let p = Placement::metric(Some(&g), 10, 10, 2.0).unwrap();
        let crs = Placement::crs_units(Some(&g), 2.0);
        assert_eq!(p, crs);
        assert_eq!(p.position(0, 0, 5.0), [500_015.0, 3_999_985.0, 10.0]);
        assert_eq!(p.frame_name(), "georeferenced");
        assert_eq!(p.frame_record()["crs"], "EPSG:32632");
        let none = Placement::metric(None, 10, 10, 1.0).unwrap();
        assert_eq!(none.frame_name(), "pixel");
        // Degrees on request, and a DEM beyond the poles refused.
        let geographic = georef([10.0, ARC3, 0.0, 58.0, 0.0, -ARC3], 2, 4326, 9102);
        let degrees = Placement::crs_units(Some(&geographic), 1.0);
        assert_eq!(degrees.position(0, 0, 1.0)[0], 10.0 + 0.5 * ARC3);
        assert_eq!(degrees.frame_record()["crs"], "EPSG:4326");
        let polar = georef([10.0, 1.0, 0.0, 91.0, 0.0, -1.0], 2, 4326, 9102);
        assert!(Placement::metric(Some(&polar), 4, 4, 1.0).is_err());
    }

    #[test]
    fn georeferenced_without_geotransform_falls_back_to_pixels() {
        let p = Placement::default();
        assert_eq!(p.frame_name(), "pixel");
        assert_eq!(p.position(4, 5, 1.0), [4.0, 5.0, 1.0]);
        assert!(!p.flips_winding());
    }

    #[test]
    fn flips_winding_follows_the_xy_determinant() {
        assert!(!Placement::pixel(1.0).flips_winding());
        assert!(!Placement::pixel(-1.0).flips_winding());
        assert!(Placement::georeferenced(NORTH_UP, 1.0).flips_winding());
        // A negative z scale does not change the view from above.
        assert!(Placement::georeferenced(NORTH_UP, -1.0).flips_winding());
        // South-up (row step positive) keeps the grid's orientation.
        let south_up = [0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        assert!(!Placement::georeferenced(south_up, 1.0).flips_winding());
        // East-west mirrored.
        let mirrored = [0.0, -1.0, 0.0, 0.0, 0.0, 1.0];
        assert!(Placement::georeferenced(mirrored, 1.0).flips_winding());
        // Swapped axes (columns go north, rows go east) mirror: det [[0, 1], [1, 0]] = −1.
        let swapped = [0.0, 0.0, 1.0, 0.0, 1.0, 0.0];
        assert!(Placement::georeferenced(swapped, 1.0).flips_winding());
        // A degenerate transform has nothing to flip.
        assert!(!Placement::georeferenced([0.0; 6], 1.0).flips_winding());
    }

    #[test]
    fn flip_makes_north_up_triangles_counter_clockwise() {
        // Grid triangle (0,0) (1,0) (0,1) in (col,row): counter-clockwise in the grid frame.
        let mesh = GridMesh {
            width: 2,
            height: 2,
            vertices: vec![0, 2, 1],
            triangles: vec![[0, 2, 1]],
        };
        let heights = [0.0; 4];
        for placement in [
            Placement::pixel(1.0),
            Placement::georeferenced(NORTH_UP, 1.0),
            Placement::georeferenced(NORTH_UP, -3.0),
        ] {
            let pos = positions(&mesh, &heights, &placement, "obj").unwrap();
            let tris = oriented_triangles(&mesh, &placement, "obj").unwrap();
            let p = |i: u32| [pos[i as usize * 3], pos[i as usize * 3 + 1]];
            for t in tris {
                let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
                let cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
                assert!(cross > 0.0, "{placement:?}");
            }
        }
    }

    #[test]
    fn bad_inputs_are_errors() {
        let mesh = GridMesh {
            width: 2,
            height: 2,
            vertices: vec![0, 1, 2],
            triangles: vec![[0, 1, 2]],
        };
        let p = Placement::pixel(1.0);
        for format in [MeshFormat::Glb, MeshFormat::Obj, MeshFormat::Ply] {
            assert!(matches!(
                encode_mesh(&mesh, &[0.0, 1.0], &p, format),
                Err(ExportError::MissingHeight { vertex: 2, .. })
            ));
            assert!(matches!(
                encode_mesh(&mesh, &[0.0, f64::NAN, 0.0, 0.0], &p, format),
                Err(ExportError::NonFiniteHeight { sample: 1, .. })
            ));
            let mut bad = mesh.clone();
            bad.triangles.push([0, 1, 3]);
            assert!(matches!(
                encode_mesh(&bad, &[0.0; 4], &p, format),
                Err(ExportError::BadTriangle {
                    triangle: 1,
                    index: 3,
                    ..
                })
            ));
            let mut outside = mesh.clone();
            outside.vertices.push(4);
            assert!(matches!(
                encode_mesh(&outside, &[0.0; 8], &p, format),
                Err(ExportError::VertexOutsideGrid { vertex: 3, .. })
            ));
            let zero_width = GridMesh {
                width: 0,
                height: 5,
                vertices: vec![0],
                triangles: vec![],
            };
            assert!(encode_mesh(&zero_width, &[0.0], &p, format).is_err());
            let huge = GridMesh {
                width: usize::MAX,
                height: 2,
                vertices: vec![],
                triangles: vec![],
            };
            assert!(matches!(
                encode_mesh(&huge, &[], &p, format),
                Err(ExportError::GridTooLarge { .. })
            ));
            let nan_scale = Placement::pixel(f64::NAN);
            assert!(matches!(
                encode_mesh(&mesh, &[0.0; 4], &nan_scale, format),
                Err(ExportError::NonFinitePosition { .. })
            ));
        }
        // f64 overflow only matters for glb's f32.
        let big = Placement::pixel(1e300);
        assert!(encode_mesh(&mesh, &[1.0; 4], &big, MeshFormat::Obj).is_ok());
        assert!(matches!(
            encode_mesh(&mesh, &[1.0; 4], &big, MeshFormat::Glb),
            Err(ExportError::NonFinitePosition { format: "glb", .. })
        ));
    }

    #[test]
    fn glb_chunks_are_padded() {
        // One triangle: 3 u16 indices = 6 bytes, so the BIN chunk needs 2 bytes of padding.
        let mesh = GridMesh {
            width: 2,
            height: 2,
            vertices: vec![0, 2, 1],
            triangles: vec![[0, 2, 1]],
        };
        let glb = encode_mesh(&mesh, &[1.0; 4], &Placement::pixel(1.0), MeshFormat::Glb).unwrap();
        assert_eq!(glb.len() % 4, 0);
        let u32_at = |o: usize| u32::from_le_bytes([glb[o], glb[o + 1], glb[o + 2], glb[o + 3]]);
        assert_eq!(u32_at(8) as usize, glb.len());
        let json_len = u32_at(12) as usize;
        assert_eq!(json_len % 4, 0);
        let bin_at = 20 + json_len;
        assert_eq!(u32_at(bin_at) as usize, 36 + 36 + 8);
        assert_eq!(&glb[bin_at + 4..bin_at + 8], b"BIN\0");
        assert_eq!(&glb[glb.len() - 2..], &[0, 0]);
        let doc: Value = serde_json::from_slice(&glb[20..bin_at]).unwrap();
        assert_eq!(doc["buffers"][0]["byteLength"], 78);
        assert_eq!(doc["accessors"][2]["componentType"], GL_UNSIGNED_SHORT);
    }
}
