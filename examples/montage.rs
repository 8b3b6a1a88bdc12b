//! Side-by-side images (level | lit | lightmap ...) for eyeballing and the
//! README. Small images are scaled up by a whole factor (nearest pixel) so
//! that every picture is at least 256 pixels tall.
//!
//! ```text
//! cargo run --release --example montage -- IMAGE... OUT.png
//! ```
use image::imageops::{self, FilterType};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((out, inputs)) = args.split_last() else {
        anyhow::bail!("usage: montage IMAGE... OUT.png");
    };
    let mut imgs = Vec::new();
    for p in inputs {
        let img = image::open(p)
            .map_err(|e| anyhow::anyhow!("{p}: {e}"))?
            .to_rgba8();
        let k = (256 / img.height().max(1)).max(1);
        imgs.push(imageops::resize(
            &img,
            img.width() * k,
            img.height() * k,
            FilterType::Nearest,
        ));
    }
    let h = imgs.iter().map(|i| i.height()).max().unwrap_or(1);
    let w: u32 = imgs.iter().map(|i| i.width() + 4).sum();
    let mut m = image::RgbaImage::from_pixel(w, h, image::Rgba([40, 40, 40, 255]));
    let mut x = 0;
    for i in &imgs {
        imageops::overlay(&mut m, i, x as i64, 0);
        x += i.width() + 4;
    }
    m.save(out)?;
    Ok(())
}
