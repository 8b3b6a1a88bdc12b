//! Side-by-side images (level | lit | lightmap) for eyeballing and the README.
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (a, out) = (&args[1..args.len() - 1], &args[args.len() - 1]);
    let imgs: Vec<image::RgbaImage> = a
        .iter()
        .map(|p| image::open(p).expect("readable image").to_rgba8())
        .collect();
    let h = imgs.iter().map(|i| i.height()).max().unwrap_or(1);
    let w: u32 = imgs.iter().map(|i| i.width() + 4).sum();
    let mut m = image::RgbaImage::from_pixel(w, h, image::Rgba([40, 40, 40, 255]));
    let mut x = 0;
    for i in &imgs {
        image::imageops::overlay(&mut m, i, x as i64, 0);
        x += i.width() + 4;
    }
    m.save(out).expect("writable output");
}
