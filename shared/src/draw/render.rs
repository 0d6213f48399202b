//! OBJ meshes to shaded PNG pictures: a small software rasteriser.
//!
//! Objects are grouped into cells by the part of their name before the first `/` (all objects
//! of `fig1/sphere` and `fig1/plane3` share the cell `fig1`); a cell's label is its name. Each
//! cell is drawn with an orthographic camera, a z-buffer, two-sided Lambert shading from one
//! light plus ambient, and the polygon edges (not the triangulation) as dark lines; the picture
//! is supersampled for smooth edges. An object's `color=RRGGBB` attribute sets its colour and
//! `edges=no` hides its edges.

use crate::geometry::mesh::PolyMesh;
use crate::math::Vec3;
use ab_glyph::{Font, FontRef, PxScale, ScaleFont};
use std::io::Write;

/// An RGB picture, 8 bits per channel, rows top to bottom.
#[derive(Clone, Debug)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<u8>,
}

impl Image {
    /// Writes the picture as PNG.
    pub fn write_png(&self, out: impl Write) -> Result<(), png::EncodingError> {
        let mut enc = png::Encoder::new(out, self.width, self.height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header()?;
        w.write_image_data(&self.rgb)?;
        w.finish()
    }
}

/// How to draw.
#[derive(Clone, Debug)]
pub struct Options {
    pub width: u32,
    pub height: u32,
    /// Cells per row (default: about square).
    pub cols: Option<usize>,
    /// Camera azimuth and elevation, degrees.
    pub azimuth: f64,
    pub elevation: f64,
    pub edges: bool,
    /// One scale for all cells (sizes comparable) instead of each cell filled.
    pub same_scale: bool,
    pub title: Option<String>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            width: 1200,
            height: 800,
            cols: None,
            azimuth: 35.0,
            elevation: 25.0,
            edges: true,
            same_scale: false,
            title: None,
        }
    }
}

/// A cell: a label and the objects drawn in it, each with its colour.
#[derive(Clone, Debug)]
pub struct Cell {
    pub label: String,
    pub objects: Vec<(PolyMesh, [f32; 3])>,
}

const PALETTE: [[u8; 3]; 6] = [
    [224, 140, 60],
    [60, 120, 200],
    [90, 170, 100],
    [200, 80, 90],
    [150, 110, 190],
    [120, 120, 120],
];

fn parse_color(s: &str) -> Option<[f32; 3]> {
    let s = s.trim_start_matches('#');
    if s.len() != 6 {
        return None;
    }
    let c = |i: usize| {
        u8::from_str_radix(&s[i..i + 2], 16)
            .ok()
            .map(|v| v as f32 / 255.0)
    };
    Some([c(0)?, c(2)?, c(4)?])
}

/// Groups meshes into cells by name prefix (before the first `/`), in order of first appearance.
pub fn group_cells(meshes: Vec<PolyMesh>) -> Vec<Cell> {
    let mut cells: Vec<Cell> = Vec::new();
    for m in meshes {
        let label = m.name.split('/').next().unwrap_or("").to_string();
        let idx = match cells.iter().position(|c| c.label == label) {
            Some(i) => i,
            None => {
                cells.push(Cell {
                    label,
                    objects: Vec::new(),
                });
                cells.len() - 1
            }
        };
        let n = cells[idx].objects.len();
        let color = m
            .attrs
            .get("color")
            .and_then(parse_color)
            .unwrap_or_else(|| PALETTE[n % PALETTE.len()].map(|v| v as f32 / 255.0));
        cells[idx].objects.push((m, color));
    }
    cells
}

const SS: usize = 2; // supersampling factor per axis

struct Canvas {
    w: usize,
    h: usize,
    color: Vec<[f32; 3]>,
    depth: Vec<f32>,
}

impl Canvas {
    fn blend(&mut self, x: usize, y: usize, c: [f32; 3], a: f32) {
        let p = &mut self.color[y * self.w + x];
        for k in 0..3 {
            p[k] = p[k] * (1.0 - a) + c[k] * a;
        }
    }
}

/// Draws the cells into one picture.
pub fn render(cells: &[Cell], opts: &Options) -> Image {
    let (w, h) = (opts.width as usize * SS, opts.height as usize * SS);
    let mut cv = Canvas {
        w,
        h,
        color: vec![[1.0; 3]; w * h],
        depth: vec![f32::NEG_INFINITY; w * h],
    };
    let font =
        FontRef::try_from_slice(dejavu::sans::regular()).expect("bundled DejaVu Sans parses");
    let title_h = if opts.title.is_some() { h / 12 } else { 0 };
    let n = cells.len().max(1);
    let cols = opts
        .cols
        .unwrap_or_else(|| {
            (n as f64 * opts.width as f64 / opts.height as f64)
                .sqrt()
                .ceil() as usize
        })
        .clamp(1, n);
    let rows = n.div_ceil(cols);
    let (cw, ch) = (w / cols, (h - title_h) / rows);
    let label_h = (ch / 9).clamp(14 * SS, 40 * SS);
    // View frame: d points from the scene to the camera, z up.
    let (az, el) = (opts.azimuth.to_radians(), opts.elevation.to_radians());
    let d = Vec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
    let right = Vec3::z().cross(&d).normalize();
    let up = d.cross(&right);
    let light = (d * 0.8 + up * 0.5 - right * 0.35).normalize();
    let bounds: Vec<(Vec3, f64)> = cells.iter().map(bounding_ball).collect();
    let max_r = bounds.iter().map(|b| b.1).fold(0.0, f64::max);
    for (i, cell) in cells.iter().enumerate() {
        let (cx0, cy0) = ((i % cols) * cw, title_h + (i / cols) * ch);
        let (centre, r) = bounds[i];
        let r = if opts.same_scale { max_r } else { r };
        if r <= 0.0 {
            continue;
        }
        let avail = (cw.min(ch - label_h)) as f64;
        let scale = 0.92 * avail / (2.0 * r);
        let ox = cx0 as f64 + cw as f64 / 2.0;
        let oy = cy0 as f64 + label_h as f64 + (ch - label_h) as f64 / 2.0;
        let project = |p: &Vec3| {
            let q = p - centre;
            [
                ox + q.dot(&right) * scale,
                oy - q.dot(&up) * scale,
                q.dot(&d) * scale,
            ]
        };
        let clip = (cx0, cy0 + label_h, cx0 + cw, cy0 + ch);
        for (mesh, color) in &cell.objects {
            let screen: Vec<[f64; 3]> = mesh.vertices.iter().map(project).collect();
            for f in 0..mesh.face_count() {
                let idx = mesh.face(f);
                let c = project(&mesh.face_centroid(f));
                let cw3 = mesh.face_centroid(f);
                for k in 0..idx.len() {
                    let (a, b) = (idx[k] as usize, idx[(k + 1) % idx.len()] as usize);
                    let n = (mesh.vertices[a] - cw3).cross(&(mesh.vertices[b] - cw3));
                    let len = n.norm();
                    if len == 0.0 {
                        continue;
                    }
                    let n = n / len;
                    let n = if n.dot(&d) < 0.0 { -n } else { n };
                    let shade = (0.38 + 0.62 * n.dot(&light).max(0.0)) as f32;
                    let col = color.map(|x| (x * shade).min(1.0));
                    fill_triangle(&mut cv, [c, screen[a], screen[b]], col, clip);
                }
            }
            if opts.edges && mesh.attrs.get("edges") != Some("no") {
                let dense = mesh.face_verts.len() > 1200;
                let thick = if dense { 0.6 } else { 1.1 } * SS as f64;
                let ecol = color.map(|x| x * 0.35);
                let bias = 0.004 * 2.0 * r * scale;
                for f in 0..mesh.face_count() {
                    let idx = mesh.face(f);
                    for k in 0..idx.len() {
                        let (a, b) = (idx[k], idx[(k + 1) % idx.len()]);
                        if a < b || mesh.face_count() == 1 {
                            draw_line(
                                &mut cv,
                                screen[a as usize],
                                screen[b as usize],
                                thick,
                                bias,
                                ecol,
                                if dense { 0.55 } else { 0.9 },
                                clip,
                            );
                        }
                    }
                }
            }
        }
        draw_text(
            &mut cv,
            &font,
            &cell.label,
            (cx0 + cw / 2) as f32,
            (cy0 + label_h / 2) as f32,
            (label_h as f32 * 0.55).min(22.0 * SS as f32),
            cw as f32 * 0.96,
        );
    }
    if let Some(t) = &opts.title {
        draw_text(
            &mut cv,
            &font,
            t,
            (w / 2) as f32,
            (title_h / 2) as f32,
            title_h as f32 * 0.5,
            w as f32 * 0.96,
        );
    }
    downsample(&cv, opts.width as usize, opts.height as usize)
}

fn bounding_ball(cell: &Cell) -> (Vec3, f64) {
    let pts: Vec<Vec3> = cell
        .objects
        .iter()
        .flat_map(|(m, _)| m.vertices.iter().copied())
        .collect();
    match crate::math::bounding_box(&pts) {
        None => (Vec3::zeros(), 0.0),
        Some((lo, hi)) => {
            let c = (lo + hi) / 2.0;
            (c, pts.iter().map(|p| (p - c).norm()).fold(0.0, f64::max))
        }
    }
}

fn fill_triangle(
    cv: &mut Canvas,
    t: [[f64; 3]; 3],
    col: [f32; 3],
    clip: (usize, usize, usize, usize),
) {
    let area =
        (t[1][0] - t[0][0]) * (t[2][1] - t[0][1]) - (t[2][0] - t[0][0]) * (t[1][1] - t[0][1]);
    if area.abs() < 1e-12 {
        return;
    }
    let (Some((xmin, xmax)), Some((ymin, ymax))) = (
        pixel_span(t.iter().map(|p| p[0]), clip.0, clip.2),
        pixel_span(t.iter().map(|p| p[1]), clip.1, clip.3),
    ) else {
        return;
    };
    let sign = area.signum();
    for y in ymin..=ymax {
        let py = y as f64 + 0.5;
        // The row's pixel centres inside all three edges, solved per edge (a sliver of a fan
        // around a face of many corners would otherwise cost its whole bounding box), a pixel
        // wider on each side for round-off; the test below decides each pixel.
        let (mut lo, mut hi) = (xmin as f64 - 0.5, xmax as f64 + 0.5);
        for (a, b) in [(t[1], t[2]), (t[2], t[0]), (t[0], t[1])] {
            let slope = sign * (b[1] - a[1]);
            let at = sign * ((b[0] - a[0]) * (py - a[1]) + (b[1] - a[1]) * a[0]);
            if slope > 0.0 {
                hi = hi.min(at / slope);
            } else if slope < 0.0 {
                lo = lo.max(at / slope);
            } else if at < 0.0 {
                hi = lo - 1.0;
            }
        }
        if hi < lo {
            continue;
        }
        let first = ((lo - 0.5).ceil() - 1.0).max(xmin as f64) as usize;
        let last = ((hi - 0.5).floor() + 1.0).min(xmax as f64) as usize;
        for x in first..=last {
            let px = x as f64 + 0.5;
            let e = |a: [f64; 3], b: [f64; 3]| {
                (b[0] - a[0]) * (py - a[1]) - (b[1] - a[1]) * (px - a[0])
            };
            let (w0, w1, w2) = (
                e(t[1], t[2]) / area,
                e(t[2], t[0]) / area,
                e(t[0], t[1]) / area,
            );
            if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                continue;
            }
            let z = (w0 * t[0][2] + w1 * t[1][2] + w2 * t[2][2]) as f32;
            let i = y * cv.w + x;
            if z > cv.depth[i] {
                cv.depth[i] = z;
                cv.color[i] = col;
            }
        }
    }
}

/// The pixels `lo..=hi` (clipped to `[min, max)`) that coordinates `values` cover; `None` when
/// they fall outside.
fn pixel_span(
    values: impl Iterator<Item = f64> + Clone,
    min: usize,
    max: usize,
) -> Option<(usize, usize)> {
    let lo = values
        .clone()
        .fold(f64::INFINITY, f64::min)
        .floor()
        .max(min as f64);
    let hi = values
        .fold(f64::NEG_INFINITY, f64::max)
        .ceil()
        .min(max as f64 - 1.0);
    (hi >= lo && hi >= 0.0).then_some((lo as usize, hi as usize))
}

#[allow(clippy::too_many_arguments)]
fn draw_line(
    cv: &mut Canvas,
    a: [f64; 3],
    b: [f64; 3],
    thick: f64,
    bias: f64,
    col: [f32; 3],
    alpha: f32,
    clip: (usize, usize, usize, usize),
) {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let pad = thick + 1.0;
    let (Some((x0, x1)), Some((y0, y1))) = (
        pixel_span(
            [a[0] - pad, b[0] - pad, a[0] + pad, b[0] + pad].into_iter(),
            clip.0,
            clip.2,
        ),
        pixel_span(
            [a[1] - pad, b[1] - pad, a[1] + pad, b[1] + pad].into_iter(),
            clip.1,
            clip.3,
        ),
    ) else {
        return;
    };
    let half = 0.5 * thick * len2.sqrt();
    for y in y0..=y1 {
        let py = y as f64 + 0.5;
        // The row's part of the band within thick/2 of the line (which holds the segment's
        // capsule), a pixel wider each side: a long diagonal line costs its length, not its
        // bounding box.
        let (first, last) = if dy.abs() > 1e-9 {
            let mid = a[0] + (py - a[1]) * dx / dy;
            let reach = (half / dy).abs() + 1.0;
            (
                ((mid - reach - 0.5).floor().max(x0 as f64) as usize),
                ((mid + reach - 0.5).ceil().min(x1 as f64) as usize),
            )
        } else {
            (x0, x1)
        };
        for x in first..=last {
            let px = x as f64 + 0.5;
            let t = if len2 > 0.0 {
                (((px - a[0]) * dx + (py - a[1]) * dy) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let (qx, qy) = (a[0] + t * dx, a[1] + t * dy);
            let dist = (crate::math::square(px - qx) + crate::math::square(py - qy)).sqrt();
            if dist > thick / 2.0 {
                continue;
            }
            let z = (a[2] + t * (b[2] - a[2])) as f32;
            let i = y * cv.w + x;
            if z + bias as f32 >= cv.depth[i] {
                cv.blend(x, y, col, alpha);
            }
        }
    }
}

/// Draws `text` centred at (cx, cy) in black.
/// Draws `text` centred on (`cx`, `cy`) at `px` pixels, smaller where it would be wider than
/// `max_width`.
fn draw_text(
    cv: &mut Canvas,
    font: &FontRef,
    text: &str,
    cx: f32,
    cy: f32,
    px: f32,
    max_width: f32,
) {
    let advance = |px: f32| -> f32 {
        let scaled = font.as_scaled(PxScale::from(px));
        (text.chars())
            .map(|c| scaled.h_advance(font.glyph_id(c)))
            .sum()
    };
    let full = advance(px);
    let (px, width) = if full > max_width && full > 0.0 {
        let px = px * max_width / full;
        (px, advance(px))
    } else {
        (px, full)
    };
    let scaled = font.as_scaled(PxScale::from(px));
    let mut x = cx - width / 2.0;
    let baseline = cy + (scaled.ascent() + scaled.descent()) / 2.0;
    for c in text.chars() {
        let g = font
            .glyph_id(c)
            .with_scale_and_position(PxScale::from(px), ab_glyph::point(x, baseline));
        x += scaled.h_advance(font.glyph_id(c));
        if let Some(outline) = font.outline_glyph(g) {
            let bb = outline.px_bounds();
            outline.draw(|gx, gy, cov| {
                let (px, py) = (bb.min.x as i64 + gx as i64, bb.min.y as i64 + gy as i64);
                if px >= 0 && py >= 0 && (px as usize) < cv.w && (py as usize) < cv.h {
                    cv.blend(px as usize, py as usize, [0.1, 0.1, 0.1], cov.min(1.0));
                }
            });
        }
    }
}

fn downsample(cv: &Canvas, w: usize, h: usize) -> Image {
    let mut rgb = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        for x in 0..w {
            let mut s = [0.0f32; 3];
            for dy in 0..SS {
                for dx in 0..SS {
                    let p = cv.color[(y * SS + dy) * cv.w + x * SS + dx];
                    for k in 0..3 {
                        s[k] += p[k];
                    }
                }
            }
            for v in s {
                rgb.push((v / (SS * SS) as f32 * 255.0).round().clamp(0.0, 255.0) as u8);
            }
        }
    }
    Image {
        width: w as u32,
        height: h as u32,
        rgb,
    }
}

/// A UV sphere of radius `r` (closed, outward), `rings` x `segments`.
pub fn uv_sphere(r: f64, rings: usize, segments: usize) -> PolyMesh {
    let mut m = PolyMesh::named("sphere");
    m.vertices.push(Vec3::new(0.0, 0.0, r));
    for i in 1..rings {
        let th = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let ph = std::f64::consts::TAU * j as f64 / segments as f64;
            m.vertices
                .push(Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()) * r);
        }
    }
    m.vertices.push(Vec3::new(0.0, 0.0, -r));
    let south = (m.vertices.len() - 1) as u32;
    let at = |i: usize, j: usize| (1 + (i - 1) * segments + j % segments) as u32;
    for j in 0..segments {
        m.push_face(&[0, at(1, j), at(1, j + 1)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            m.push_face(&[at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    for j in 0..segments {
        m.push_face(&[at(rings - 1, j), south, at(rings - 1, j + 1)]);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mass::MassProps;

    #[test]
    fn uv_sphere_is_closed_and_outward() {
        let s = uv_sphere(2.0, 16, 32);
        s.topology(None).unwrap();
        let m = MassProps::of(&s);
        assert!(
            m.volume > 0.0
                && (m.volume / (4.0 / 3.0 * std::f64::consts::PI * 8.0) - 1.0).abs() < 0.05
        );
    }

    fn canvas(w: usize, h: usize) -> Canvas {
        Canvas {
            w,
            h,
            color: vec![[1.0; 3]; w * h],
            depth: vec![f32::NEG_INFINITY; w * h],
        }
    }

    /// The row-by-row spans of triangles and lines cover exactly the pixels that the test of
    /// every pixel in the picture covers, slivers (a fan round a face of many corners, long
    /// diagonal edges) and shapes partly outside the picture included.
    #[test]
    fn row_spans_cover_what_testing_every_pixel_covers() {
        use crate::math::square;
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (w, h) = (64, 48);
        let clip = (0, 0, w, h);
        for case in 0..400 {
            let mut p = || {
                [
                    rng.random_range(-20.0..84.0),
                    rng.random_range(-20.0..68.0),
                    0.0,
                ]
            };
            let (a, b, mut c) = (p(), p(), p());
            if case % 2 == 0 {
                // A sliver: c a hair off the line a-b.
                let t = 0.37;
                c = [
                    a[0] + t * (b[0] - a[0]) + 0.01,
                    a[1] + t * (b[1] - a[1]),
                    0.0,
                ];
            }
            let mut cv = canvas(w, h);
            fill_triangle(&mut cv, [a, b, c], [0.0; 3], clip);
            let area = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
            let mut lines = canvas(w, h);
            draw_line(&mut lines, a, b, 2.5, 0.0, [0.0; 3], 1.0, clip);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            for y in 0..h {
                for x in 0..w {
                    let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                    let e = |u: [f64; 3], v: [f64; 3]| {
                        (v[0] - u[0]) * (py - u[1]) - (v[1] - u[1]) * (px - u[0])
                    };
                    let filled = area.abs() >= 1e-12
                        && [e(b, c), e(c, a), e(a, b)].iter().all(|v| v / area >= 0.0);
                    assert_eq!(
                        cv.color[y * w + x] == [0.0; 3],
                        filled,
                        "triangle {case} at {x},{y}"
                    );
                    let t = (((px - a[0]) * dx + (py - a[1]) * dy) / (dx * dx + dy * dy))
                        .clamp(0.0, 1.0);
                    let d = (square(px - a[0] - t * dx) + square(py - a[1] - t * dy)).sqrt();
                    assert_eq!(
                        lines.color[y * w + x] == [0.0; 3],
                        d <= 1.25,
                        "line {case} at {x},{y}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_cube_is_drawn_in_its_cell_and_the_rest_stays_white() {
        let cells = group_cells(vec![crate::geometry::mesh::cube(1.0)]);
        let img = render(
            &cells,
            &Options {
                width: 120,
                height: 100,
                ..Default::default()
            },
        );
        let px = |x: usize, y: usize| &img.rgb[(y * 120 + x) * 3..(y * 120 + x) * 3 + 3];
        assert_eq!(px(1, 99), [255, 255, 255]);
        let centre = px(60, 60);
        assert!(
            centre != [255, 255, 255],
            "the cube covers the middle of its cell"
        );
        let mut buf = Vec::new();
        img.write_png(&mut buf).unwrap();
        assert_eq!(&buf[1..4], b"PNG");
    }
}
