//! Where a mesh's x/y live: the DEM's horizontal CRS, read from its GeoKeys, and the local
//! east-north-up frame that geographic DEMs are meshed in.
//!
//! A geographic DEM (longitude/latitude in degrees, heights in metres) meshed as is gives
//! a needle: a degree is ~100 km. [`HorizontalCrs::of`] tells geographic CRSs from
//! projected ones, and [`LocalFrame`] maps longitude, latitude and height to metres east,
//! north and up of an origin on the WGS 84 ellipsoid (geodetic → ECEF → ENU, `f64`).
//!
//! Heights are taken as heights above the ellipsoid. DEM heights are usually above the
//! geoid instead, which is within ~100 m of the ellipsoid and nearly constant across a
//! DEM, so the shape is kept; only the frame's vertical origin is off by that amount.

use wavemesh_codec::geokey::{
    self, ANGULAR_UNITS, GEOGRAPHIC_TYPE, MODEL_GEOGRAPHIC, MODEL_PROJECTED, MODEL_TYPE,
    PROJECTED_TYPE, USER_DEFINED,
};
use wavemesh_codec::Georef;

/// WGS 84 semi-major axis, metres.
pub const WGS84_A: f64 = 6_378_137.0;
/// WGS 84 flattening.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;
/// WGS 84 first eccentricity squared, `f·(2 − f)`.
const WGS84_E2: f64 = WGS84_F * (2.0 - WGS84_F);

/// Why a DEM's CRS cannot be put in a local metric frame.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FrameError {
    /// The geographic CRS measures angles in a unit this does not know.
    #[error("geographic CRS with angular unit {0} (GeogAngularUnitsGeoKey), which wavemesh does not know; use --xy degrees or --xy pixel")]
    UnknownAngularUnit(u16),
    /// The geotransform puts samples beyond the poles.
    #[error("geographic DEM with latitudes from {0} to {1} degrees, beyond ±90; use --xy degrees or --xy pixel")]
    LatitudeOutOfRange(f64, f64),
}

/// A DEM's horizontal coordinate reference system, as far as its GeoKeys tell.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum HorizontalCrs {
    /// No GeoKeys say which (an `.asc` grid, a world file, a raster without keys).
    #[default]
    Unknown,
    /// Longitude and latitude.
    Geographic {
        /// EPSG code of the CRS (`None` when user-defined or not given).
        epsg: Option<u16>,
        /// Degrees in one unit of the geotransform (1 for degrees).
        degrees_per_unit: f64,
    },
    /// Projected coordinates (metres or the projection's own units).
    Projected {
        /// EPSG code of the CRS (`None` when user-defined or not given).
        epsg: Option<u16>,
    },
}

impl HorizontalCrs {
    /// The CRS of `georef` from its GeoKey directory: geographic when `GTModelTypeGeoKey`
    /// is 2 (or, without a model type, when only a geographic CRS code is given),
    /// projected when it is 1 (or only a projected code is given), unknown otherwise.
    pub fn of(georef: &Georef) -> Result<HorizontalCrs, FrameError> {
        let keys = &georef.geo_key_directory;
        let code = |key| geokey::value(keys, key).filter(|&c| c != 0 && c != USER_DEFINED);
        let geographic = match geokey::value(keys, MODEL_TYPE) {
            Some(MODEL_GEOGRAPHIC) => true,
            Some(MODEL_PROJECTED) => false,
            Some(_) => return Ok(HorizontalCrs::Unknown),
            None => match (
                geokey::value(keys, GEOGRAPHIC_TYPE),
                geokey::value(keys, PROJECTED_TYPE),
            ) {
                (Some(_), None) => true,
                (_, Some(_)) => false,
                (None, None) => return Ok(HorizontalCrs::Unknown),
            },
        };
        if !geographic {
            return Ok(HorizontalCrs::Projected {
                epsg: code(PROJECTED_TYPE),
            });
        }
        // EPSG angular unit codes.
        let degrees_per_unit = match geokey::value(keys, ANGULAR_UNITS) {
            None | Some(9102) => 1.0,                   // degree (the default)
            Some(9101) => 180.0 / std::f64::consts::PI, // radian
            Some(9103) => 1.0 / 60.0,                   // arc-minute
            Some(9104) => 1.0 / 3600.0,                 // arc-second
            Some(9105) | Some(9106) => 0.9,             // grad, gon
            Some(unit) => return Err(FrameError::UnknownAngularUnit(unit)),
        };
        Ok(HorizontalCrs::Geographic {
            epsg: code(GEOGRAPHIC_TYPE),
            degrees_per_unit,
        })
    }

    /// A short label: `EPSG:4326`, `geographic (user-defined)`, `projected
    /// (user-defined)` or `unknown`.
    pub fn label(&self) -> String {
        match self {
            HorizontalCrs::Unknown => "unknown".into(),
            HorizontalCrs::Geographic { epsg: Some(c), .. }
            | HorizontalCrs::Projected { epsg: Some(c) } => format!("EPSG:{c}"),
            HorizontalCrs::Geographic { epsg: None, .. } => "geographic (user-defined)".into(),
            HorizontalCrs::Projected { epsg: None } => "projected (user-defined)".into(),
        }
    }
}

/// Earth-centred, earth-fixed coordinates (metres) of longitude `lon` and latitude `lat`
/// (degrees) at height `h` (metres) above the WGS 84 ellipsoid.
pub fn geodetic_to_ecef(lon: f64, lat: f64, h: f64) -> [f64; 3] {
    let (sin_lat, cos_lat) = lat.to_radians().sin_cos();
    let (sin_lon, cos_lon) = lon.to_radians().sin_cos();
    // Prime vertical radius of curvature.
    let n = WGS84_A / (1.0 - WGS84_E2 * sin_lat * sin_lat).sqrt();
    [
        (n + h) * cos_lat * cos_lon,
        (n + h) * cos_lat * sin_lon,
        (n * (1.0 - WGS84_E2) + h) * sin_lat,
    ]
}

/// An east-north-up frame tangent to the WGS 84 ellipsoid: x east, y north, z up
/// (along the ellipsoid's normal), metres from the origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalFrame {
    /// Origin longitude, degrees.
    pub lon: f64,
    /// Origin latitude, degrees.
    pub lat: f64,
    /// Origin height above the ellipsoid, metres.
    pub height: f64,
    /// The origin in ECEF.
    origin: [f64; 3],
    /// Rows of the ECEF → ENU rotation: east, north, up unit vectors in ECEF.
    axes: [[f64; 3]; 3],
    /// Metres a degree of longitude and of latitude spans at the origin (the radii of
    /// curvature there): [`LocalFrame::tangent`]'s scales.
    metres_per_degree: [f64; 2],
}

impl LocalFrame {
    /// The frame at longitude `lon`, latitude `lat` (degrees) and `height` (metres).
    pub fn at(lon: f64, lat: f64, height: f64) -> LocalFrame {
        let (sin_lat, cos_lat) = lat.to_radians().sin_cos();
        let (sin_lon, cos_lon) = lon.to_radians().sin_cos();
        let w2 = 1.0 - WGS84_E2 * sin_lat * sin_lat;
        // Prime vertical and meridian radii of curvature.
        let n = WGS84_A / w2.sqrt();
        let m = WGS84_A * (1.0 - WGS84_E2) / (w2 * w2.sqrt());
        LocalFrame {
            lon,
            lat,
            height,
            origin: geodetic_to_ecef(lon, lat, height),
            axes: [
                [-sin_lon, cos_lon, 0.0],
                [-sin_lat * cos_lon, -sin_lat * sin_lon, cos_lat],
                [cos_lat * cos_lon, cos_lat * sin_lon, sin_lat],
            ],
            metres_per_degree: [n * cos_lat, m].map(|r| r * 1f64.to_radians()),
        }
    }

    /// East, north and up (metres) of the ECEF point `p`.
    pub fn ecef_to_enu(&self, p: [f64; 3]) -> [f64; 3] {
        let d = [
            p[0] - self.origin[0],
            p[1] - self.origin[1],
            p[2] - self.origin[2],
        ];
        self.axes
            .map(|axis| axis[0] * d[0] + axis[1] * d[1] + axis[2] * d[2])
    }

    /// East, north and up (metres) of longitude `lon`, latitude `lat` (degrees) at height
    /// `h` (metres).
    pub fn enu(&self, lon: f64, lat: f64, h: f64) -> [f64; 3] {
        self.ecef_to_enu(geodetic_to_ecef(lon, lat, h))
    }

    /// Metres east and north of the origin in the frame's tangent plane, to first order:
    /// longitude and latitude (degrees) scaled by the ellipsoid's radii of curvature at
    /// the origin (the derivatives of [`LocalFrame::enu`] there). Straight lines stay
    /// straight, so a grid maps to a grid; at ±0.5° of latitude from the origin east
    /// distances are off by about `tan(lat) · 0.9 %`, and the ground does not curve away.
    pub fn tangent(&self, lon: f64, lat: f64) -> [f64; 2] {
        let [east, north] = self.metres_per_degree;
        [east * (lon - self.lon), north * (lat - self.lat)]
    }

    /// The frame of a geographic DEM: at the centre of its `width × height` grid
    /// (geotransform `gt` in degrees), height 0. Refuses latitudes beyond ±90.
    pub fn of_grid(gt: &[f64; 6], width: usize, height: usize) -> Result<LocalFrame, FrameError> {
        let at = |col: f64, row: f64| {
            [
                gt[0] + col * gt[1] + row * gt[2],
                gt[3] + col * gt[4] + row * gt[5],
            ]
        };
        let (w, h) = (width as f64, height as f64);
        let corners = [
            at(0.5, 0.5),
            at(w - 0.5, 0.5),
            at(0.5, h - 0.5),
            at(w - 0.5, h - 0.5),
        ];
        let lo = corners.iter().map(|c| c[1]).fold(f64::INFINITY, f64::min);
        let hi = corners
            .iter()
            .map(|c| c[1])
            .fold(f64::NEG_INFINITY, f64::max);
        if !(lo >= -90.0 && hi <= 90.0) {
            return Err(FrameError::LatitudeOutOfRange(lo, hi));
        }
        let [lon, lat] = at(w / 2.0, h / 2.0);
        Ok(LocalFrame::at(lon, lat, 0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// WGS 84 semi-minor axis, metres.
    const WGS84_B: f64 = WGS84_A * (1.0 - WGS84_F);

    fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
        a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= tol)
    }

    /// Longitude, latitude (degrees) and height of an ECEF point, by fixed-point iteration
    /// on the latitude (an independent inverse for the round trips).
    fn ecef_to_geodetic(p: [f64; 3]) -> [f64; 3] {
        let lon = p[1].atan2(p[0]);
        let r = p[0].hypot(p[1]);
        let mut lat = p[2].atan2(r * (1.0 - WGS84_E2));
        let mut h = 0.0;
        for _ in 0..10 {
            let n = WGS84_A / (1.0 - WGS84_E2 * lat.sin().powi(2)).sqrt();
            h = r / lat.cos() - n;
            lat = p[2].atan2(r * (1.0 - WGS84_E2 * n / (n + h)));
        }
        [lon.to_degrees(), lat.to_degrees(), h]
    }

    #[test]
    fn the_tangent_plane_is_the_local_frame_to_first_order() {
        for (lon, lat) in [(11.5, 57.5), (-97.0, 0.0), (140.0, -35.0)] {
            let frame = LocalFrame::at(lon, lat, 0.0);
            assert_eq!(frame.tangent(lon, lat), [0.0, 0.0]);
            // A step of 1e-4° (about 10 m): the second-order terms are millimetres.
            for (d_lon, d_lat) in [(1e-4, 0.0), (0.0, 1e-4), (-1e-4, 2e-4)] {
                let [e, n] = frame.tangent(lon + d_lon, lat + d_lat);
                let enu = frame.enu(lon + d_lon, lat + d_lat, 0.0);
                assert!(close([e, n, 0.0], [enu[0], enu[1], 0.0], 1e-3), "{enu:?}");
            }
        }
        // A degree of latitude at 57.5° N times the meridian's radius of curvature there.
        let north = LocalFrame::at(11.5, 57.5, 0.0).tangent(11.5, 58.5)[1];
        assert!((north - 111_369.0).abs() < 5.0, "{north}");
    }

    #[test]
    fn ecef_of_known_points() {
        assert!(close(
            geodetic_to_ecef(0.0, 0.0, 0.0),
            [WGS84_A, 0.0, 0.0],
            1e-9
        ));
        assert!(close(
            geodetic_to_ecef(90.0, 0.0, 10.0),
            [0.0, WGS84_A + 10.0, 0.0],
            1e-9
        ));
        assert!(close(
            geodetic_to_ecef(0.0, 90.0, 0.0),
            [0.0, 0.0, WGS84_B],
            1e-9
        ));
        assert!(close(
            geodetic_to_ecef(0.0, -90.0, 0.0),
            [0.0, 0.0, -WGS84_B],
            1e-9
        ));
        // pymap3d's test point and a GNSS tool's example, to the millimetre.
        assert!(close(
            geodetic_to_ecef(-82.0, 42.0, 200.0),
            [660_675.251_824_7, -4_700_948.683_16, 4_245_737.662_22],
            1e-3
        ));
        assert!(close(
            geodetic_to_ecef(132.414_780_4, 34.440_106_1, 233.362),
            [-3_551_876.829, 3_887_786.860, 3_586_946.387],
            1e-3
        ));
    }

    #[test]
    fn enu_of_known_points() {
        let frame = LocalFrame::at(0.0, 0.0, 0.0);
        assert!(close(frame.enu(0.0, 0.0, 100.0), [0.0, 0.0, 100.0], 1e-9));
        // A quarter turn east: the point is a east of the origin and a below its plane.
        assert!(close(
            frame.enu(90.0, 0.0, 0.0),
            [WGS84_A, 0.0, -WGS84_A],
            1e-6
        ));
        // The north pole: b north, a below.
        assert!(close(
            frame.enu(0.0, 90.0, 0.0),
            [0.0, WGS84_B, -WGS84_A],
            1e-6
        ));
        // pymap3d's ENU test (its target rounded to 1e-6 degrees, so within 5 mm).
        let frame = LocalFrame::at(-82.0, 42.0, 200.0);
        assert!(close(
            frame.enu(-81.997_752, 42.002_582, 1139.702),
            [186.277_521, 286.842_22, 939.692_62],
            5e-3
        ));
    }

    #[test]
    fn small_steps_are_the_ellipsoids_radii_of_curvature() {
        let lat = 36.5f64;
        let frame = LocalFrame::at(-84.2, lat, 0.0);
        let s = lat.to_radians().sin();
        let w = (1.0 - WGS84_E2 * s * s).sqrt();
        let n = WGS84_A / w;
        let m = WGS84_A * (1.0 - WGS84_E2) / (w * w * w);
        let d = 1e-4f64;
        let east = frame.enu(-84.2 + d, lat, 0.0);
        let north = frame.enu(-84.2, lat + d, 0.0);
        let expect_east = n * lat.to_radians().cos() * d.to_radians();
        let expect_north = m * d.to_radians();
        assert!(
            (east[0] - expect_east).abs() < 1e-4 * expect_east,
            "{east:?}"
        );
        assert!(
            (north[1] - expect_north).abs() < 1e-4 * expect_north,
            "{north:?}"
        );
        // A parallel curves north of the east axis: by (8.9 m)²·tan φ / 2N ≈ 5 µm here.
        assert!(east[1] > 0.0 && east[1] < 1e-5, "{east:?}");
        assert!(north[0].abs() < 1e-9, "{north:?}");
    }

    #[test]
    fn round_trips_through_ecef_and_enu() {
        let frame = LocalFrame::at(11.5, 57.5, 0.0);
        for &(lon, lat, h) in &[
            (11.0, 57.0, 163.0),
            (12.0, 58.0, -6.0),
            (-179.9, -89.5, 4000.0),
            (179.99, 0.0, 0.0),
            (-84.5, 36.4, 1076.0),
        ] {
            let p = geodetic_to_ecef(lon, lat, h);
            let [lon2, lat2, h2] = ecef_to_geodetic(p);
            assert!(
                (lon2 - lon).abs() < 1e-11 && (lat2 - lat).abs() < 1e-11,
                "{lon} {lat}"
            );
            assert!((h2 - h).abs() < 1e-6, "{h} {h2}");
            // ENU is a rigid motion of ECEF: distances are kept.
            let e = frame.ecef_to_enu(p);
            let o = geodetic_to_ecef(frame.lon, frame.lat, frame.height);
            let dist =
                ((p[0] - o[0]).powi(2) + (p[1] - o[1]).powi(2) + (p[2] - o[2]).powi(2)).sqrt();
            let norm = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
            assert!((dist - norm).abs() < 1e-6 * dist.max(1.0));
        }
    }

    fn georef_with_keys(keys: &[[u16; 4]]) -> Georef {
        let mut dir = vec![1, 1, 0, keys.len() as u16];
        for k in keys {
            dir.extend_from_slice(k);
        }
        Georef {
            geo_key_directory: dir,
            ..Georef::default()
        }
    }

    #[test]
    fn crs_from_geokeys() {
        let wgs84 = georef_with_keys(&[[1024, 0, 1, 2], [1025, 0, 1, 1], [2048, 0, 1, 4326]]);
        assert_eq!(
            HorizontalCrs::of(&wgs84),
            Ok(HorizontalCrs::Geographic {
                epsg: Some(4326),
                degrees_per_unit: 1.0
            })
        );
        assert_eq!(HorizontalCrs::of(&wgs84).unwrap().label(), "EPSG:4326");
        let utm = georef_with_keys(&[[1024, 0, 1, 1], [3072, 0, 1, 32632]]);
        assert_eq!(
            HorizontalCrs::of(&utm),
            Ok(HorizontalCrs::Projected { epsg: Some(32632) })
        );
        // No model type: the CRS code decides.
        let nad27 = georef_with_keys(&[[2048, 0, 1, 4267]]);
        assert!(matches!(
            HorizontalCrs::of(&nad27),
            Ok(HorizontalCrs::Geographic {
                epsg: Some(4267),
                ..
            })
        ));
        let user = georef_with_keys(&[[1024, 0, 1, 2], [2048, 0, 1, 32767], [2054, 0, 1, 9105]]);
        assert_eq!(
            HorizontalCrs::of(&user),
            Ok(HorizontalCrs::Geographic {
                epsg: None,
                degrees_per_unit: 0.9
            })
        );
        let odd_unit = georef_with_keys(&[[1024, 0, 1, 2], [2054, 0, 1, 9122]]);
        assert_eq!(
            HorizontalCrs::of(&odd_unit),
            Err(FrameError::UnknownAngularUnit(9122))
        );
        assert_eq!(
            HorizontalCrs::of(&Georef::default()),
            Ok(HorizontalCrs::Unknown)
        );
        let geocentric = georef_with_keys(&[[1024, 0, 1, 3]]);
        assert_eq!(HorizontalCrs::of(&geocentric), Ok(HorizontalCrs::Unknown));
        // A truncated directory is read as far as it goes.
        assert_eq!(
            HorizontalCrs::of(&Georef {
                geo_key_directory: vec![1, 1, 0, 5, 1024, 0, 1],
                ..Georef::default()
            }),
            Ok(HorizontalCrs::Unknown)
        );
    }

    #[test]
    fn grid_frame_is_at_the_centre_and_refuses_latitudes_beyond_the_poles() {
        let gt = [-84.5, 0.001, 0.0, 36.8, 0.0, -0.001];
        let frame = LocalFrame::of_grid(&gt, 400, 300).unwrap();
        assert!((frame.lon - -84.3).abs() < 1e-12 && (frame.lat - 36.65).abs() < 1e-12);
        assert_eq!(frame.height, 0.0);
        let polar = [0.0, 1.0, 0.0, 95.0, 0.0, -1.0];
        assert!(matches!(
            LocalFrame::of_grid(&polar, 10, 10),
            Err(FrameError::LatitudeOutOfRange(..))
        ));
    }
}
