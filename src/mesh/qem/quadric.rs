//! Quadric error of a vertex position: the sum of squared *vertical* distances to a set
//! of planes (each plane of a grid triangle written as `z = αx + βy + γ`), so the cost of
//! a contraction is in squared data units, whatever the grid spacing.

/// A symmetric 4 × 4 quadric on `(x, y, z, 1)`, its ten distinct coefficients.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Quadric([f64; 10]);

impl Quadric {
    /// The quadric of the plane through three points `(column, row, height)` measuring
    /// vertical distance; `None` when the points are collinear seen from above.
    pub fn of_triangle(points: [[f64; 3]; 3]) -> Option<Quadric> {
        let [p, q, r] = points;
        let u = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
        let v = [r[0] - p[0], r[1] - p[1], r[2] - p[2]];
        let normal = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        if normal[2] == 0.0 {
            return None;
        }
        let d = -(normal[0] * p[0] + normal[1] * p[1] + normal[2] * p[2]);
        // Dividing by the normal's z makes the residual the vertical distance.
        let [a, b, c, d] = [normal[0], normal[1], normal[2], d].map(|k| k / normal[2]);
        Some(Quadric([
            a * a,
            a * b,
            a * c,
            a * d,
            b * b,
            b * c,
            b * d,
            c * c,
            c * d,
            d * d,
        ]))
    }

    /// Adds `other`'s planes to this quadric's.
    pub fn add(&mut self, other: &Quadric) {
        for (k, o) in self.0.iter_mut().zip(other.0) {
            *k += o;
        }
    }

    /// The sum of squared vertical distances from `(x, y, z)` to the planes (never
    /// negative: rounding below zero is clamped).
    pub fn cost_at(&self, [x, y, z]: [f64; 3]) -> f64 {
        let [xx, xy, xz, xw, yy, yz, yw, zz, zw, ww] = self.0;
        let cost = xx * x * x
            + yy * y * y
            + zz * z * z
            + ww
            + 2.0 * (xy * x * y + xz * x * z + xw * x + yz * y * z + yw * y + zw * z);
        cost.max(0.0)
    }

    /// The sum of two quadrics.
    pub fn sum(&self, other: &Quadric) -> Quadric {
        let mut out = *self;
        out.add(other);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plane_costs_the_squared_vertical_distance() {
        // z = 2x + 3y + 1 through three points.
        let plane = |x: f64, y: f64| 2.0 * x + 3.0 * y + 1.0;
        let q = Quadric::of_triangle([
            [0.0, 0.0, plane(0.0, 0.0)],
            [1.0, 0.0, plane(1.0, 0.0)],
            [0.0, 1.0, plane(0.0, 1.0)],
        ])
        .unwrap();
        assert!(q.cost_at([5.0, 7.0, plane(5.0, 7.0)]) < 1e-9);
        let off = q.cost_at([5.0, 7.0, plane(5.0, 7.0) + 4.0]);
        assert!((off - 16.0).abs() < 1e-9, "{off}");
    }

    #[test]
    fn quadrics_add_their_costs() {
        let flat = Quadric::of_triangle([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        let raised = Quadric::of_triangle([[0.0, 0.0, 2.0], [1.0, 0.0, 2.0], [0.0, 1.0, 2.0]]);
        let both = flat.unwrap().sum(&raised.unwrap());
        assert!((both.cost_at([3.0, 3.0, 1.0]) - 2.0).abs() < 1e-9);
        assert!(Quadric::of_triangle([[0.0; 3], [1.0, 1.0, 0.0], [2.0, 2.0, 5.0]]).is_none());
    }
}
