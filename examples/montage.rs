//! Side-by-side images (level | lit | lightmap ...) for eyeballing and the
//! README. Small images are scaled up by a whole factor (nearest pixel) so
//! that every picture is at least 256 pixels tall; with `--height H` every
//! picture is scaled (nearest pixel) to exactly `H` pixels tall instead.
//!
//! An input `IMAGE@X,Y,W,H` is the rectangle of `IMAGE` at `X, Y` (its
//! top-left corner, in pixels, fractions allowed) of `W x H` pixels, for
//! lining a baked view up with an editor's screenshot of the same place.
//!
//! ```text
//! cargo run --release --example montage -- [--height H] IMAGE[@X,Y,W,H]... OUT.png
//! ```
use image::imageops::{self, FilterType};
use image::{Rgba, RgbaImage};

/// The `w x h` rectangle of `img` at `x, y` as a `cw x ch` picture, each
/// pixel the source pixel under its centre (nearest pixel; outside the
/// image is black).
fn crop(img: &RgbaImage, [x, y, w, h]: [f64; 4], cw: u32, ch: u32) -> RgbaImage {
    RgbaImage::from_fn(cw, ch, |i, j| {
        let sx = (x + (i as f64 + 0.5) * w / cw as f64).floor();
        let sy = (y + (j as f64 + 0.5) * h / ch as f64).floor();
        if sx >= 0.0 && sy >= 0.0 && (sx as u32) < img.width() && (sy as u32) < img.height() {
            *img.get_pixel(sx as u32, sy as u32)
        } else {
            Rgba([0, 0, 0, 255])
        }
    })
}

fn main() -> anyhow::Result<()> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut height = None;
    if let Some(at) = args.iter().position(|a| a == "--height") {
        let h: u32 = args
            .get(at + 1)
            .and_then(|h| h.parse().ok())
            .filter(|h| *h > 0)
            .ok_or_else(|| anyhow::anyhow!("--height takes a positive number of pixels"))?;
        height = Some(h);
        args.drain(at..at + 2);
    }
    let Some((out, inputs)) = args.split_last() else {
        anyhow::bail!("usage: montage [--height H] IMAGE[@X,Y,W,H]... OUT.png");
    };
    let mut imgs = Vec::new();
    for arg in inputs {
        let (p, rect) = match arg.rsplit_once('@') {
            Some((p, r)) => {
                let v: Vec<f64> = r
                    .split(',')
                    .map(|n| n.trim().parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|e| anyhow::anyhow!("{arg}: {e}"))?;
                let rect: [f64; 4] = v
                    .try_into()
                    .map_err(|_| anyhow::anyhow!("{arg}: a rectangle is X,Y,W,H"))?;
                (p, Some(rect))
            }
            None => (arg.as_str(), None),
        };
        let mut img = image::open(p)
            .map_err(|e| anyhow::anyhow!("{p}: {e}"))?
            .to_rgba8();
        let (iw, ih) = match rect {
            Some([_, _, w, h]) => (w, h),
            None => (img.width() as f64, img.height() as f64),
        };
        let (w, h) = match height {
            Some(h) => (((iw * h as f64 / ih.max(1e-9)).round() as u32).max(1), h),
            None => {
                let k = (256 / (ih.round() as u32).max(1)).max(1);
                (
                    iw.round().max(1.0) as u32 * k,
                    ih.round().max(1.0) as u32 * k,
                )
            }
        };
        if let Some(rect) = rect {
            img = crop(&img, rect, w, h);
        }
        imgs.push(imageops::resize(&img, w, h, FilterType::Nearest));
    }
    let h = imgs.iter().map(|i| i.height()).max().unwrap_or(1);
    let w: u32 = imgs.iter().map(|i| i.width() + 4).sum();
    let mut m = RgbaImage::from_pixel(w, h, Rgba([40, 40, 40, 255]));
    let mut x = 0;
    for i in &imgs {
        imageops::overlay(&mut m, i, x as i64, 0);
        x += i.width() + 4;
    }
    m.save(out)?;
    Ok(())
}
