//! A perspective camera over the terrain: position, look-at point, vertical field of view
//! and viewport; its view frustum, the projection of points to pixels, of a region's area
//! to pixels², and of a height error at a distance to pixels.
//!
//! World frame: the terrain's output frame (x, y as the mesh file has them, z = height ×
//! z-scale), z up.

use glam::{DMat3, DMat4, DVec2, DVec3};

use super::ViewError;

/// Distance in front of the eye below which points count as behind it.
const NEAR: f64 = 1e-6;

/// A perspective camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: DVec3,
    /// The point looked at.
    pub look: DVec3,
    /// Vertical field of view, degrees.
    pub fov_degrees: f64,
    /// Viewport width and height, pixels.
    pub viewport: (u32, u32),
}

/// The camera's orthonormal frame and projection constants, derived once per frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// The camera it describes.
    pub camera: Camera,
    /// World → camera space (glam's right-handed look-at: x right, y up, −z forward).
    pub view: DMat4,
    /// Unit forward direction.
    pub forward: DVec3,
    /// Unit right direction.
    pub right: DVec3,
    /// Unit up direction (of the image).
    pub up: DVec3,
    /// tan(fov/2) vertically and horizontally.
    tan_half: DVec2,
    /// Pixels a unit length at distance 1 covers (viewport height / (2 tan(fov/2))).
    pub pixels_per_unit: f64,
    /// The cosine of the angle between the view axis and the frustum's corner rays: a
    /// point in the frustum at distance `r` from the eye lies at depth `r ·` this or more.
    pub corner_cosine: f64,
    /// The four side planes and the near plane, inward unit normals through the eye.
    planes: [DVec3; 5],
}

impl Camera {
    /// A camera at `eye` looking at `look`.
    ///
    /// # Errors
    /// [`ViewError::Camera`] when a coordinate is not finite, `eye == look`, the field of
    /// view is outside (0, 180) degrees or the viewport is empty.
    pub fn new(
        eye: DVec3,
        look: DVec3,
        fov_degrees: f64,
        viewport: (u32, u32),
    ) -> Result<Camera, ViewError> {
        let bad = |why: &str| Err(ViewError::Camera(why.to_string()));
        if !(eye.is_finite() && look.is_finite()) {
            return bad("camera and look-at coordinates must be finite");
        }
        if eye.distance(look) <= 1e-9 * eye.length().max(1.0) {
            return bad("the camera and the look-at point must differ");
        }
        if !(fov_degrees > 0.0 && fov_degrees < 180.0) {
            return bad("the field of view must be between 0 and 180 degrees");
        }
        if viewport.0 == 0 || viewport.1 == 0 {
            return bad("the viewport must be at least 1×1 pixels");
        }
        Ok(Camera {
            eye,
            look,
            fov_degrees,
            viewport,
        })
    }

    /// The frame and constants of this camera.
    pub fn view(&self) -> View {
        let forward = (self.look - self.eye).normalize();
        // World z is up, unless looking straight along it (then the image's up is −y,
        // north in pixel units).
        let world_up = if forward.cross(DVec3::Z).length() < 1e-6 {
            DVec3::NEG_Y
        } else {
            DVec3::Z
        };
        let view = DMat4::look_at_rh(self.eye, self.look, world_up);
        let right = forward.cross(world_up).normalize();
        let up = right.cross(forward);
        let (w, h) = (f64::from(self.viewport.0), f64::from(self.viewport.1));
        let tan_v = (self.fov_degrees.to_radians() * 0.5).tan();
        let tan_h = tan_v * w / h;
        let planes = [
            (right + forward * tan_h).normalize(),
            (-right + forward * tan_h).normalize(),
            (up + forward * tan_v).normalize(),
            (-up + forward * tan_v).normalize(),
            forward,
        ];
        View {
            camera: *self,
            view,
            forward,
            right,
            up,
            tan_half: DVec2::new(tan_h, tan_v),
            pixels_per_unit: h / (2.0 * tan_v),
            corner_cosine: 1.0 / (1.0 + tan_h * tan_h + tan_v * tan_v).sqrt(),
            planes,
        }
    }
}

impl View {
    /// Pixel coordinates (x right, y down from the top-left corner) of world point `p`, and
    /// its depth along the view direction; `None` behind the eye.
    pub fn project(&self, p: DVec3) -> Option<(DVec2, f64)> {
        let q = self.view.transform_point3(p);
        let depth = -q.z;
        if depth <= NEAR {
            return None;
        }
        let (w, h) = (
            f64::from(self.camera.viewport.0),
            f64::from(self.camera.viewport.1),
        );
        let ndc = DVec2::new(q.x, q.y) / (depth * self.tan_half);
        Some((
            DVec2::new((ndc.x + 1.0) * 0.5 * w, (1.0 - ndc.y) * 0.5 * h),
            depth,
        ))
    }

    /// Area in pixels² of the quadrilateral `corners` (in order around it) projected on
    /// the view plane; `None` when a corner is behind the eye.
    pub fn projected_area(&self, corners: [DVec3; 4]) -> Option<f64> {
        let mut points = [DVec2::ZERO; 4];
        for (p, c) in points.iter_mut().zip(corners) {
            *p = self.project(c)?.0;
        }
        let twice: f64 = (0..4)
            .map(|k| points[k].perp_dot(points[(k + 1) % 4]))
            .sum();
        Some(0.5 * twice.abs())
    }

    /// The most pixels a vertical segment of length `error` (world units) spans on screen
    /// when its points lie at most `reach` from the eye horizontally and at depth `depth`
    /// or more: `error · f · reach / depth²` (`f` = [`View::pixels_per_unit`]).
    ///
    /// Why: moving a point `q` (relative to the eye) up by `dt` moves its image by
    /// `f · |F × (z × q)| / (q·F)² · dt` pixels (`F` the view axis, `z` up), and
    /// `|F × (z × q)| ≤ |z × q|`, the point's horizontal distance. Seen from above a
    /// height error shrinks with the horizontal distance (Lindstrom et al.'s vertical
    /// foreshortening); off the view axis the image stretches with 1 / depth².
    #[inline]
    pub fn vertical_error_pixels(&self, error: f64, reach: f64, depth: f64) -> f64 {
        let depth = depth.max(NEAR);
        error * self.pixels_per_unit * reach / (depth * depth)
    }

    /// A lower bound on the depth of every point of the box `lo..=hi` that lies inside
    /// the view frustum, `distance` being the box's distance from the eye: the depth of
    /// its nearest corner along the view axis, and at least `distance` times
    /// [`View::corner_cosine`].
    #[inline]
    pub fn seen_depth(&self, lo: DVec3, hi: DVec3, distance: f64) -> f64 {
        let nearest = DVec3::select(self.forward.cmpge(DVec3::ZERO), lo, hi);
        self.forward
            .dot(nearest - self.camera.eye)
            .max(distance * self.corner_cosine)
    }

    /// Viewport area, pixels².
    pub fn viewport_area(&self) -> f64 {
        f64::from(self.camera.viewport.0) * f64::from(self.camera.viewport.1)
    }

    /// How far the box `lo..=hi` reaches into the view frustum, in world units: the
    /// smallest, over the frustum's planes, distance of the box's farthest corner in
    /// front of the plane. Negative when the box lies outside (by minus that much), so
    /// the frustum meets the box while the camera moves less than a positive clearance.
    #[inline]
    pub fn frustum_clearance(&self, lo: DVec3, hi: DVec3) -> f64 {
        let eye = self.camera.eye;
        let mut clearance = f64::INFINITY;
        for n in &self.planes {
            // The box corner farthest along the plane's inward normal.
            let p = DVec3::select(n.cmpge(DVec3::ZERO), hi, lo);
            clearance = clearance.min(n.dot(p - eye));
        }
        clearance
    }

    /// How far the box `lo..=hi` lies outside the view frustum (0 when it meets it).
    #[inline]
    pub fn outside_distance(&self, lo: DVec3, hi: DVec3) -> f64 {
        (-self.frustum_clearance(lo, hi)).max(0.0)
    }

    /// The rotation angle (radians) between this camera's frame and `other`'s.
    pub fn rotation_to(&self, other: &View) -> f64 {
        let a = DMat3::from_cols(self.right, self.up, self.forward);
        let b = DMat3::from_cols(other.right, other.up, other.forward);
        let r = b * a.transpose();
        let cos = ((r.x_axis.x + r.y_axis.y + r.z_axis.z - 1.0) * 0.5).clamp(-1.0, 1.0);
        cos.acos()
    }
}

/// Distance from `p` to the box `lo..=hi` (0 inside it).
#[inline]
pub fn box_distance(p: DVec3, lo: DVec3, hi: DVec3) -> f64 {
    (lo - p).max(p - hi).max(DVec3::ZERO).length()
}

/// The largest distance from `p` to a point of the box `lo..=hi`.
#[inline]
pub fn farthest_distance(p: DVec3, lo: DVec3, hi: DVec3) -> f64 {
    (p - lo).abs().max((hi - p).abs()).length()
}

/// The largest horizontal (x, y) distance from `p` to a point of the box `lo..=hi`.
#[inline]
pub fn horizontal_reach(p: DVec3, lo: DVec3, hi: DVec3) -> f64 {
    let far = (p - lo).abs().max((hi - p).abs());
    far.truncate().length()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> View {
        Camera::new(DVec3::new(0.0, 0.0, 10.0), DVec3::ZERO, 90.0, (200, 100))
            .unwrap()
            .view()
    }

    #[test]
    fn the_look_at_point_projects_to_the_centre() {
        let view = camera();
        let (p, depth) = view.project(DVec3::ZERO).unwrap();
        assert!((p - DVec2::new(100.0, 50.0)).length() < 1e-9);
        assert!((depth - 10.0).abs() < 1e-9);
        // 90° vertical: the top edge of the image is 10 units up at depth 10.
        assert!((view.pixels_per_unit - 50.0).abs() < 1e-9);
        assert!(view.project(DVec3::new(0.0, 0.0, 11.0)).is_none());
    }

    #[test]
    fn frustum_distances() {
        let view = camera();
        let unit = DVec3::splat(0.5);
        assert_eq!(view.outside_distance(-unit, unit), 0.0);
        // Behind the eye: outside by its distance behind the near plane.
        let behind = DVec3::new(0.0, 0.0, 20.0);
        assert!((view.outside_distance(behind - unit, behind + unit) - 9.5).abs() < 1e-9);
        // Far to a side at depth 10: outside.
        let side = DVec3::new(100.0, 0.0, 0.0);
        assert!(view.outside_distance(side - unit, side + unit) > 10.0);
    }

    #[test]
    fn area_of_a_square_facing_the_camera() {
        let view = camera();
        let c = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .map(|(x, y)| DVec3::new(x, y, 0.0));
        // 2 units at depth 10 → 10 pixels a side.
        assert!((view.projected_area(c).unwrap() - 100.0).abs() < 1e-6);
        assert!((box_distance(DVec3::new(3.0, 0.0, 0.0), -unit3(), unit3()) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn vertical_errors_project_within_their_bound() {
        let view = Camera::new(
            DVec3::new(0.0, 0.0, 50.0),
            DVec3::new(40.0, 10.0, 0.0),
            60.0,
            (160, 90),
        )
        .unwrap()
        .view();
        let mut next = crate::view::unit_random(12345);
        let (mut seen, mut tightest) = (0, 0.0f64);
        for _ in 0..20000 {
            let p = DVec3::new(next() * 120.0 - 20.0, next() * 120.0 - 60.0, next() * 30.0);
            let error = next() * 5.0;
            let q = p + DVec3::Z * error;
            if view.outside_distance(p, p) > 0.0 || view.outside_distance(q, q) > 0.0 {
                continue;
            }
            let (a, b) = (view.project(p).unwrap().0, view.project(q).unwrap().0);
            let (lo, hi) = (p, q);
            let reach = horizontal_reach(view.camera.eye, lo, hi);
            let depth = view.seen_depth(lo, hi, box_distance(view.camera.eye, lo, hi));
            let bound = view.vertical_error_pixels(error, reach, depth);
            assert!(a.distance(b) <= bound * (1.0 + 1e-9) + 1e-9);
            tightest = tightest.max(a.distance(b) / bound.max(1e-12));
            seen += 1;
        }
        assert!(seen > 1000);
        // Not loose: some errors project to most of their bound.
        assert!(tightest > 0.8, "{tightest}");
    }

    fn unit3() -> DVec3 {
        DVec3::ONE
    }
}
