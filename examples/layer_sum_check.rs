use flatbake::output::read_lightmap_exr;
fn main() {
    let mut a = std::env::args().skip(1);
    let full = a.next().unwrap();
    let (_, _, f) = read_lightmap_exr(full.as_ref()).unwrap();
    let mut s = vec![[0f32; 3]; f.len()];
    for l in a {
        let (_, _, v) = read_lightmap_exr(l.as_ref()).unwrap();
        for (x, y) in s.iter_mut().zip(&v) {
            for c in 0..3 {
                x[c] += y[c];
            }
        }
    }
    let (mut d, mut m, mut rel) = (0f64, 0f64, 0f64);
    for (x, y) in f.iter().zip(&s) {
        for c in 0..3 {
            let e = (x[c] as f64 - y[c] as f64).abs();
            d = d.max(e);
            m = m.max(x[c] as f64);
            if x[c] > 0.01 {
                rel = rel.max(e / x[c] as f64);
            }
        }
    }
    println!("max abs error {d:e}, max value {m}, max rel error (values > 0.01) {rel:e}");
}
