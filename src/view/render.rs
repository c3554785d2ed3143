//! Frames a person can look at: the terrain from above (hillshade of the true heights),
//! every cell of the view mesh tinted by its size (red finest to blue coarsest) with its
//! outline where it is large enough to see, and the camera's position and horizontal
//! field of view, as a PNG written atomically.

use std::path::Path;

use glam::{DMat2, DVec2};
use image::{Rgb, RgbImage};

use super::camera::View;
use super::selection::ViewTerrain;
use super::ViewError;
use crate::atomic::write_atomic;
use crate::mesh::cells::CellTree;

/// Draws the cells of `tree` over `terrain` seen from above, with `view`'s camera, at
/// most `max_side` pixels a side.
pub fn top_down(
    terrain: &ViewTerrain<'_>,
    tree: &CellTree,
    view: &View,
    max_side: u32,
) -> RgbImage {
    let heights = terrain.heights();
    let (w, h) = (heights.width, heights.height);
    let scale = f64::from(max_side.max(16)) / (w.max(h).max(2) - 1) as f64;
    let scale = scale.min(4.0);
    let (iw, ih) = (
        (((w - 1) as f64 * scale) as u32).max(1) + 1,
        (((h - 1) as f64 * scale) as u32).max(1) + 1,
    );
    let mut image = hillshade(terrain, iw, ih, scale);
    let levels = terrain.levels().max(1);
    for &cell in tree.leaves() {
        let (x0, y0, x1, y1) = tree.bounds(cell);
        let corner = |x: usize, y: usize| DVec2::new(x as f64 * scale, y as f64 * scale);
        let (a, b) = (corner(x0, y0), corner(x1, y1));
        tint(&mut image, a, b, level_colour(cell.level, levels));
        if (b.x - a.x).min(b.y - a.y) >= 4.0 {
            let outline = Rgb([30, 30, 30]);
            let (c, d) = (DVec2::new(b.x, a.y), DVec2::new(a.x, b.y));
            for (p, q) in [(a, c), (c, b), (b, d), (d, a)] {
                draw_line(&mut image, p, q, outline);
            }
        }
    }
    draw_camera(terrain, &mut image, view, scale);
    image
}

/// Red for grid cells through yellow and green to blue for the roots.
fn level_colour(level: u32, levels: u32) -> [f64; 3] {
    let t = f64::from(level) / f64::from(levels);
    let stops = [
        [230.0, 40.0, 40.0],
        [240.0, 200.0, 40.0],
        [60.0, 190.0, 80.0],
        [50.0, 90.0, 230.0],
    ];
    let x = t * 3.0;
    let k = (x.floor() as usize).min(2);
    let u = x - k as f64;
    [0, 1, 2].map(|c| stops[k][c] + u * (stops[k + 1][c] - stops[k][c]))
}

/// Blends `colour` at 45 % over the pixels of the rectangle `a..=b`.
fn tint(image: &mut RgbImage, a: DVec2, b: DVec2, colour: [f64; 3]) {
    let (x0, y0) = (a.x.round().max(0.0) as u32, a.y.round().max(0.0) as u32);
    let (x1, y1) = (
        (b.x.round() as u32).min(image.width() - 1),
        (b.y.round() as u32).min(image.height() - 1),
    );
    for y in y0..=y1 {
        for x in x0..=x1 {
            let p = image.get_pixel_mut(x, y);
            for (channel, target) in p.0.iter_mut().zip(colour) {
                *channel = (0.55 * f64::from(*channel) + 0.45 * target) as u8;
            }
        }
    }
}

/// Grey hillshade of the true heights, lit from the north-west; nodata in dark blue.
fn hillshade(terrain: &ViewTerrain<'_>, iw: u32, ih: u32, scale: f64) -> RgbImage {
    let heights = terrain.heights();
    let (w, h) = (heights.width, heights.height);
    let z_scale = terrain.placement().z_scale;
    let at = |x: usize, y: usize| heights.values[y.min(h - 1) * w + x.min(w - 1)] * z_scale;
    RgbImage::from_fn(iw, ih, |px, py| {
        let x = ((f64::from(px) / scale) as usize).min(w - 1);
        let y = ((f64::from(py) / scale) as usize).min(h - 1);
        if terrain.is_void(0, x.min(w.saturating_sub(2)), y.min(h.saturating_sub(2))) {
            return Rgb([20, 30, 70]);
        }
        let (dx, dy) = (
            at(x + 1, y) - at(x.saturating_sub(1), y),
            at(x, y + 1) - at(x, y.saturating_sub(1)),
        );
        let normal = glam::DVec3::new(-dx, -dy, 2.0).normalize();
        let light = glam::DVec3::new(-1.0, -1.0, 1.5).normalize();
        let g = (60.0 + 180.0 * normal.dot(light).max(0.0)) as u8;
        Rgb([g, g, g])
    })
}

/// The eye as a dot and the horizontal field of view as two rays, on the ground plan.
fn draw_camera(terrain: &ViewTerrain<'_>, image: &mut RgbImage, view: &View, scale: f64) {
    let origin = terrain.world(0, 0, 0.0).truncate();
    let axes = DMat2::from_cols(
        terrain.world(1, 0, 0.0).truncate() - origin,
        terrain.world(0, 1, 0.0).truncate() - origin,
    );
    if axes.determinant() == 0.0 {
        return;
    }
    let inverse = axes.inverse();
    let to_image = |p: DVec2| inverse * (p - origin) * scale;
    let eye = to_image(view.camera.eye.truncate());
    let (w, h) = (
        f64::from(view.camera.viewport.0),
        f64::from(view.camera.viewport.1),
    );
    let tan_h = (view.camera.fov_degrees.to_radians() * 0.5).tan() * w / h;
    let reach = f64::from(image.width().max(image.height())) * 2.0;
    let colour = Rgb([250, 210, 0]);
    for side in [-1.0, 1.0] {
        let ray = (view.forward + view.right * (side * tan_h)).truncate();
        let direction = (inverse * ray).normalize_or_zero();
        draw_line(image, eye, eye + direction * reach, colour);
    }
    for dy in -3i32..=3 {
        for dx in -3i32..=3 {
            put(
                image,
                eye.x as i64 + i64::from(dx),
                eye.y as i64 + i64::from(dy),
                colour,
            );
        }
    }
}

fn put(image: &mut RgbImage, x: i64, y: i64, colour: Rgb<u8>) {
    if x >= 0
        && y >= 0
        && (x as u64) < u64::from(image.width())
        && (y as u64) < u64::from(image.height())
    {
        image.put_pixel(x as u32, y as u32, colour);
    }
}

/// A one-pixel line from `a` to `b`, clipped to the image.
fn draw_line(image: &mut RgbImage, a: DVec2, b: DVec2, colour: Rgb<u8>) {
    let bound = f64::from(image.width().max(image.height())) * 4.0;
    let (a, b) = (
        a.clamp(DVec2::splat(-bound), DVec2::splat(bound)),
        b.clamp(DVec2::splat(-bound), DVec2::splat(bound)),
    );
    let steps = (b - a).abs().max_element().ceil().max(1.0) as usize;
    for k in 0..=steps {
        let p = a.lerp(b, k as f64 / steps as f64);
        put(image, p.x.round() as i64, p.y.round() as i64, colour);
    }
}

/// Writes `image` as a PNG to `path` atomically.
///
/// # Errors
/// [`ViewError::Render`] when encoding or writing fails.
pub fn write_png(path: &Path, image: &RgbImage) -> Result<(), ViewError> {
    let mut bytes = Vec::new();
    image
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .map_err(|e| ViewError::Render(e.to_string()))?;
    write_atomic(path, |w| w.write_all(&bytes))
        .map_err(|e| ViewError::Render(format!("{}: {e}", path.display())))
}
