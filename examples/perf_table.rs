//! Prints the performance tables of `docs/performance.md`:
//!
//! ```text
//! cargo build --release --bins --examples && target/release/examples/perf_table [--quick] [--max SIZE]
//! ```
//!
//! * Level size: `synth::bench_obstacles(size, 60, 12, 7)` (60 obstacles, a
//!   dozen lights, falloff size / 12) at 128 to 2048 px, each baked by the
//!   real `flatbake bake` binary (whole process, `normal` quality) under
//!   `/usr/bin/time` for wall time and peak memory; stage times come from the
//!   report JSON.
//! * Edge count: the 512 px level with 15 to 240 obstacles.
//! * Patch count: the 512 px level at `draft`, `normal` and `high`.
//! * Naive against fast: `synth::bench_scattered(size, 40, 3, 7)` baked in
//!   this process with both gathers on the same patches and the same solve;
//!   the gather stage times are compared, and so are the lightmaps (the fast
//!   gather is exact for the given radiosity; the naive one samples points
//!   on each patch, 8 and 64 of them). All are compared with the `reference`
//!   bake, so each ratio is stated with both errors.
//!
//! * Level classes: every class of `synth::hard_classes` (the level kinds that
//!   cost most, timed against the speed targets: a shooter
//!   map, a courtyard map, pillar and light fields, checkerboards, wall
//!   noise, corridors, dots, the 8192 px benchmark) baked by the binary at
//!   `normal`, and the real maps at `draft` too. Each row gives s / Mpx and
//!   its ratio to the 512 px benchmark's s / Mpx measured at the start of the
//!   same run, and to the mean of the benchmark baked once just before and
//!   once just after the row (on a shared machine whose speed drifts within a
//!   run, the nearby ratio is the steadier one), peak memory per pixel, and
//!   the gather's share of the bake. A bake that is refused (too much
//!   memory), killed or times out is a row saying so.
//!
//! `--quick` stops the size table at 512, skips the 128 px naive runs and the
//! classes above 1 Mpx. `--classes` prints only the classes table;
//! `--only TEXT` (repeatable) keeps the classes whose name or label holds
//! TEXT; `--small SIZE` uses `synth::small_classes(SIZE)` instead.
//! `--bin PATH` bakes with that `flatbake` binary instead of the one beside
//! this example; `--before PATH` also bakes every class with a second binary,
//! interleaved (before, after, before, ...), and adds a before / after table.
//! `--timeout SECS` (default 600) kills a bake that runs longer.
//! Timings are wall time on whatever machine runs this; the load average is
//! printed with the tables because the numbers depend on it.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use flatbake_core::bake::{GatherMethod, Settings, bake};
use flatbake_core::level::{Cell, Level};
use flatbake_core::quality::Quality;
use flatbake_synth::{self as synth, Painted};

struct Run {
    wall: f64,
    /// User + system CPU seconds of the process (less sensitive to load).
    cpu: Option<f64>,
    peak_mb: Option<f64>,
    report: serde_json::Value,
}

/// How one bake by the binary ended.
enum Outcome {
    Baked(Run),
    /// The binary exited with an error (e.g. refused for memory); the first
    /// line of what it said.
    Failed(String),
    /// Killed by a signal (the OOM killer, say) before it finished.
    Killed(String),
    /// Still running after the timeout, and killed.
    TimedOut(f64),
}

impl Outcome {
    /// The run, or an error: for the tables that expect every bake to work.
    fn run(self) -> anyhow::Result<Run> {
        match self {
            Outcome::Baked(r) => Ok(r),
            other => anyhow::bail!("bake did not finish: {}", other.why()),
        }
    }

    fn why(&self) -> String {
        match self {
            Outcome::Baked(_) => "baked".into(),
            Outcome::Failed(m) => format!("failed: {m}"),
            Outcome::Killed(m) => format!("killed ({m})"),
            Outcome::TimedOut(t) => format!("timed out after {t:.0} s"),
        }
    }
}

/// The `flatbake` binary beside this example's folder (`target/release`).
fn sibling_bin() -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe()?;
    let dir = exe
        .parent()
        .and_then(Path::parent)
        .ok_or_else(|| anyhow::anyhow!("cannot locate the target folder"))?;
    let bin = dir.join("flatbake");
    if !bin.exists() {
        anyhow::bail!(
            "{} not found: run `cargo build --release --bins --examples` first",
            bin.display()
        );
    }
    Ok(bin)
}

/// How the driver bakes: which binary, and how long one bake may take.
struct Baker {
    bin: PathBuf,
    timeout: f64,
}

impl Baker {
    /// Saves `level` into `dir` and bakes it (whole process).
    fn bake(&self, dir: &Path, level: &Painted, quality: &str) -> anyhow::Result<Outcome> {
        level.save(dir)?;
        self.bake_saved(dir, &level.name, quality)
    }

    /// Bakes `dir/NAME.png`, saved before, with the binary under
    /// `/usr/bin/time` (whole process: load, bake, write), into `dir/out`.
    /// A bake that fails, is killed or outlives the timeout is an
    /// [`Outcome`], not an error.
    fn bake_saved(&self, dir: &Path, name: &str, quality: &str) -> anyhow::Result<Outcome> {
        let png = dir.join(format!("{name}.png"));
        let out = dir.join("out");
        let report_path = out.join(format!("{name}.report.json"));
        let _ = std::fs::remove_file(&report_path);
        let timed = Path::new("/usr/bin/time").exists();
        let mut cmd = if timed {
            let mut c = Command::new("/usr/bin/time");
            c.arg("-f").arg("PERF_TABLE %e %M %U %S").arg(&self.bin);
            c
        } else {
            Command::new(&self.bin)
        };
        let err_path = dir.join("stderr.txt");
        cmd.args(["bake", "--quiet", "--force", "-q", quality, "-o"])
            .arg(&out)
            .arg(&png)
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&err_path)?);
        // Its own process group, so a timeout kills the bake and not only
        // /usr/bin/time.
        #[cfg(unix)]
        std::os::unix::process::CommandExt::process_group(&mut cmd, 0);
        let t = Instant::now();
        let mut child = cmd.spawn()?;
        let status = loop {
            if let Some(s) = child.try_wait()? {
                break s;
            }
            if t.elapsed().as_secs_f64() > self.timeout {
                kill_group(&mut child);
                return Ok(Outcome::TimedOut(self.timeout));
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        };
        let mut wall = t.elapsed().as_secs_f64();
        let stderr = std::fs::read_to_string(&err_path).unwrap_or_default();
        let said = || {
            stderr
                .lines()
                .find(|l| !l.starts_with("PERF_TABLE") && !l.trim().is_empty())
                .unwrap_or("")
                .trim()
                .to_string()
        };
        // /usr/bin/time reports a child killed by a signal on stderr and
        // exits with 128 + signal.
        #[cfg(unix)]
        if let Some(sig) = std::os::unix::process::ExitStatusExt::signal(&status) {
            return Ok(Outcome::Killed(format!("signal {sig}")));
        }
        if let Some(l) = stderr
            .lines()
            .find(|l| l.contains("Command terminated by signal"))
        {
            return Ok(Outcome::Killed(l.trim().to_string()));
        }
        if !status.success() || !report_path.exists() {
            let code = status
                .code()
                .map_or("no exit code".into(), |c| format!("exit {c}"));
            return Ok(Outcome::Failed(format!("{code}: {}", said())));
        }
        let mut peak_mb = None;
        let mut cpu = None;
        for line in stderr.lines() {
            if let Some(rest) = line.strip_prefix("PERF_TABLE ") {
                let mut it = rest.split_whitespace();
                if let Some(w) = it.next().and_then(|v| v.parse::<f64>().ok()) {
                    wall = w;
                }
                peak_mb = it
                    .next()
                    .and_then(|v| v.parse::<f64>().ok())
                    .map(|kb| kb / 1024.0);
                let user = it.next().and_then(|v| v.parse::<f64>().ok());
                let sys = it.next().and_then(|v| v.parse::<f64>().ok());
                cpu = user.zip(sys).map(|(u, s)| u + s);
            }
        }
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report_path)?)?;
        Ok(Outcome::Baked(Run {
            wall,
            cpu,
            peak_mb,
            report,
        }))
    }
}

/// Kills the process group of `child` (the bake under `/usr/bin/time`).
fn kill_group(child: &mut std::process::Child) {
    #[cfg(unix)]
    {
        let _ = Command::new("kill")
            .args(["-KILL", "--", &format!("-{}", child.id())])
            .status();
    }
    let _ = child.kill();
    let _ = child.wait();
}

fn stage(r: &Run, name: &str) -> f64 {
    r.report["timings"][name].as_f64().unwrap_or(0.0)
}

fn count(r: &Run, name: &str) -> u64 {
    r.report["counts"][name].as_u64().unwrap_or(0)
}

fn header() {
    println!(
        "| level | px | edges | patches | geometry s | F s | solve s | gather s | bake s | process s | CPU s | s / Mpx | peak MB |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
}

fn row(label: &str, size: usize, r: &Run) {
    let mpx = (size * size) as f64 / 1e6;
    println!(
        "| {label} | {size}x{size} | {} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {} | {:.2} | {} |",
        count(r, "edges"),
        count(r, "patches"),
        stage(r, "geometry"),
        stage(r, "form_factors"),
        stage(r, "solve"),
        stage(r, "gather"),
        stage(r, "total"),
        r.wall,
        r.cpu.map_or("n/a".into(), |c| format!("{c:.2}")),
        r.wall / mpx,
        r.peak_mb.map_or("n/a".into(), |m| format!("{m:.0}")),
    );
}

fn load_level(p: &Painted) -> anyhow::Result<(Level, Option<f64>)> {
    let (lv, palette) = p.level()?;
    Ok((lv, palette.settings.falloff))
}

/// Floor-pixel light of a `normal` bake, and the gather stage time.
fn bake_floor(lv: &Level, gather: GatherMethod, samples: usize) -> anyhow::Result<(Vec<f32>, f64)> {
    bake_floor_at(lv, Quality::Normal, gather, samples)
}

fn bake_floor_at(
    lv: &Level,
    quality: Quality,
    gather: GatherMethod,
    samples: usize,
) -> anyhow::Result<(Vec<f32>, f64)> {
    let mut s = Settings::new(quality);
    s.gather = gather;
    s.naive_samples = samples;
    let b = bake(lv, &s, &|_| {})?;
    let v = lv
        .cells
        .iter()
        .zip(&b.lightmap.rgb)
        .filter(|(c, _)| **c == Cell::Floor)
        .flat_map(|(_, v)| *v)
        .collect();
    Ok((v, b.report.timings.gather))
}

/// RMS and largest difference of `a` against `reference`, relative to the
/// reference's RMS.
fn rel_err(a: &[f32], reference: &[f32]) -> (f64, f64) {
    let n = reference.len().max(1) as f64;
    let rms_ref = (reference.iter().map(|v| (*v as f64).powi(2)).sum::<f64>() / n).sqrt();
    let rms = (a
        .iter()
        .zip(reference)
        .map(|(x, y)| (*x as f64 - *y as f64).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    let max = a
        .iter()
        .zip(reference)
        .map(|(x, y)| (*x as f64 - *y as f64).abs())
        .fold(0.0, f64::max);
    (rms / rms_ref, max / rms_ref)
}

/// One class baked at one quality: what each binary gave.
struct ClassRow {
    name: String,
    quality: &'static str,
    px: usize,
    before: Option<Outcome>,
    after: Outcome,
}

fn print_load(when: &str) {
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "load average {when}: {}",
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
}

/// Saves the 512 px benchmark in `dir`, for [`bench_s_per_mpx`]; returns
/// its name.
fn save_bench(dir: &Path) -> anyhow::Result<String> {
    let level = synth::bench_obstacles(512, 60, 12, 7);
    level.save(dir)?;
    Ok(level.name)
}

/// Seconds per megapixel of the 512 px benchmark `name`, saved in `dir`
/// ([`save_bench`]) (best of `rounds`, whole process) with each of
/// `bakers` (NaN for one that cannot bake it): the yardstick every class
/// is compared with.
fn bench_s_per_mpx(
    dir: &Path,
    name: &str,
    bakers: &[&Baker],
    rounds: usize,
) -> anyhow::Result<Vec<f64>> {
    let mut best = vec![f64::INFINITY; bakers.len()];
    for _ in 0..rounds {
        for (b, baker) in best.iter_mut().zip(bakers) {
            match baker.bake_saved(dir, name, "normal")? {
                Outcome::Baked(r) => *b = b.min(r.wall),
                other => {
                    println!(
                        "The benchmark did not bake with {}: {}",
                        baker.bin.display(),
                        other.why()
                    );
                    *b = f64::NAN;
                }
            }
        }
    }
    Ok(best.iter().map(|w| w / (512.0 * 512.0 / 1e6)).collect())
}

/// The "Level classes" table: every class of `flatbake_synth::hard_classes`
/// (or `small_classes(size)`) baked at `normal`, and the real maps also at
/// `draft`, with `after` (and `before`, interleaved, when given).
fn classes_table(
    dir: &Path,
    after: &Baker,
    before: Option<&Baker>,
    only: &[String],
    small: Option<usize>,
    max_px: Option<usize>,
) -> anyhow::Result<()> {
    let classes = match small {
        Some(s) => synth::small_classes(s),
        None => synth::hard_classes(),
    };
    let classes: Vec<_> = classes
        .into_iter()
        .filter(|c| max_px.is_none_or(|m| c.level.width * c.level.height <= m))
        .filter(|c| {
            only.is_empty()
                || only
                    .iter()
                    .any(|o| c.level.name.contains(o.as_str()) || c.label.contains(o.as_str()))
        })
        .collect();
    let mut bakers = vec![after];
    bakers.extend(before);
    // Saved once: the benchmark is baked again beside every row.
    let bench_name = save_bench(dir)?;
    let bench = bench_s_per_mpx(dir, &bench_name, &bakers, 3)?;
    println!("\n### Level classes (whole process, `flatbake bake`)\n");
    println!(
        "Benchmark (512 px, 60 obstacles, normal, best of 3) in this run: {:.3} s / Mpx{}. `x bench` is a level's s / Mpx over that; `x bench nearby` over the mean of the benchmark baked once just before the level's row and once just after it (a shared machine's speed drifts over a run); `gather` the gather's share of the bake time; timeout {:.0} s per bake.\n",
        bench[0],
        before.map_or(String::new(), |_| format!(
            " ({:.3} s / Mpx with the before binary)",
            bench[1]
        )),
        after.timeout
    );
    println!(
        "| level | class | size | quality | edges | patches | wall s | CPU s | s / Mpx | x bench | x bench nearby | peak MB | B / px | gather |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut rows = Vec::new();
    // The benchmark baked once between rows, by the binary under test: each
    // row's ratio is also taken against the two around it.
    let mut bench_before_row = bench_s_per_mpx(dir, &bench_name, &[after], 1)?[0];
    for c in &classes {
        let p = &c.level;
        p.save(dir)?;
        let px = p.width * p.height;
        // Edges traced here for levels a failed bake has no report for.
        let traced = if px <= 4200 * 1000 {
            let (lv, _) = p.level()?;
            Some(flatbake_core::geometry::trace(&lv).edges.len())
        } else {
            None
        };
        let qualities: &[&'static str] = if c.real_map {
            &["draft", "normal"]
        } else {
            &["normal"]
        };
        for &q in qualities {
            let b = match before {
                Some(b) => Some(b.bake_saved(dir, &p.name, q)?),
                None => None,
            };
            let a = after.bake_saved(dir, &p.name, q)?;
            let bench_after_row = bench_s_per_mpx(dir, &bench_name, &[after], 1)?[0];
            let nearby = 0.5 * (bench_before_row + bench_after_row);
            bench_before_row = bench_after_row;
            let size = format!("{}x{}", p.width, p.height);
            let head = format!("| {} | {} | {size} | {q} |", p.name, c.label);
            match &a {
                Outcome::Baked(r) => {
                    let mpx = px as f64 / 1e6;
                    let total = stage(r, "total");
                    println!(
                        "{head} {} | {} | {:.2} | {} | {:.2} | {:.1} | {:.2} | {} | {} | {:.0}% |",
                        count(r, "edges"),
                        count(r, "patches"),
                        r.wall,
                        r.cpu.map_or("n/a".into(), |c| format!("{c:.2}")),
                        r.wall / mpx,
                        r.wall / mpx / bench[0],
                        r.wall / mpx / nearby,
                        r.peak_mb.map_or("n/a".into(), |m| format!("{m:.0}")),
                        r.peak_mb.map_or("n/a".into(), |m| format!(
                            "{:.0}",
                            m * 1024.0 * 1024.0 / px as f64
                        )),
                        100.0 * stage(r, "gather") / total.max(1e-9),
                    );
                }
                other => println!(
                    "{head} {} | - | {} | - | - | - | - | - | - | - |",
                    traced.map_or("-".into(), |e| e.to_string()),
                    other.why()
                ),
            }
            use std::io::Write as _;
            std::io::stdout().flush()?;
            rows.push(ClassRow {
                name: p.name.clone(),
                quality: q,
                px,
                before: b,
                after: a,
            });
        }
    }
    if before.is_some() {
        println!("\n#### Before and after, interleaved in this run\n");
        println!(
            "| level | quality | before wall s | after wall s | after / before | before CPU s | after CPU s | before peak MB | after peak MB | before x bench | after x bench |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|---|");
        for r in &rows {
            let mpx = r.px as f64 / 1e6;
            let cell = |o: &Outcome, f: &dyn Fn(&Run) -> String| match o {
                Outcome::Baked(run) => f(run),
                other => other.why(),
            };
            let b = r.before.as_ref().expect("baked with both");
            let wall = |o: &Outcome| cell(o, &|x| format!("{:.2}", x.wall));
            // The reason a bake did not finish is given once, in its wall column.
            let num = |o: &Outcome, f: &dyn Fn(&Run) -> String| match o {
                Outcome::Baked(run) => f(run),
                _ => "-".into(),
            };
            let cpu = |o: &Outcome| num(o, &|x| x.cpu.map_or("n/a".into(), |c| format!("{c:.2}")));
            let peak = |o: &Outcome| {
                num(o, &|x| {
                    x.peak_mb.map_or("n/a".into(), |m| format!("{m:.0}"))
                })
            };
            let ratio = match (b, &r.after) {
                (Outcome::Baked(x), Outcome::Baked(y)) => format!("{:.2}", y.wall / x.wall),
                _ => "-".into(),
            };
            println!(
                "| {} | {} | {} | {} | {ratio} | {} | {} | {} | {} | {} | {} |",
                r.name,
                r.quality,
                wall(b),
                wall(&r.after),
                cpu(b),
                cpu(&r.after),
                peak(b),
                peak(&r.after),
                num(b, &|x| format!("{:.1}", x.wall / mpx / bench[1])),
                num(&r.after, &|x| format!("{:.1}", x.wall / mpx / bench[0])),
            );
        }
    }
    Ok(())
}

const USAGE: &str = "usage: perf_table [--quick] [--max SIZE] [--classes] [--only TEXT]... [--small SIZE] [--bin PATH] [--before PATH] [--timeout SECS]";

fn main() -> anyhow::Result<()> {
    let mut quick = false;
    let mut max = 2048;
    let mut classes_only = false;
    let mut only = Vec::new();
    let mut small = None;
    let mut bin = None;
    let mut before_bin: Option<PathBuf> = None;
    let mut timeout = 600.0;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = |what: &str| {
            args.next()
                .ok_or_else(|| anyhow::anyhow!("{a} needs {what}\n{USAGE}"))
        };
        match a.as_str() {
            "--quick" => quick = true,
            "--max" => {
                max = value("a size")?
                    .parse()
                    .map_err(|_| anyhow::anyhow!("--max needs a size"))?
            }
            "--classes" => classes_only = true,
            "--only" => only.push(value("a part of a level name")?),
            "--small" => {
                small = Some(
                    value("a size")?
                        .parse()
                        .map_err(|_| anyhow::anyhow!("--small needs a size"))?,
                )
            }
            "--bin" => bin = Some(PathBuf::from(value("a path")?)),
            "--before" => before_bin = Some(PathBuf::from(value("a path")?)),
            "--timeout" => {
                timeout = value("seconds")?
                    .parse()
                    .ok()
                    .filter(|t: &f64| *t > 0.0)
                    .ok_or_else(|| anyhow::anyhow!("--timeout needs seconds above 0"))?
            }
            _ => {
                println!("{USAGE}");
                return Ok(());
            }
        }
    }
    if quick {
        max = max.min(512);
    }
    let baker = Baker {
        bin: match bin {
            Some(b) => b,
            None => sibling_bin()?,
        },
        timeout,
    };
    let before = before_bin.map(|bin| Baker { bin, timeout });
    for b in std::iter::once(&baker).chain(&before) {
        if !b.bin.exists() {
            anyhow::bail!("{} not found", b.bin.display());
        }
    }
    let dir = tempfile::tempdir()?;
    println!(
        "flatbake perf_table: {} logical cores, binary {}{}",
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        baker.bin.display(),
        before
            .as_ref()
            .map_or(String::new(), |b| format!(", before {}", b.bin.display()))
    );
    print_load("at start");
    if classes_only {
        classes_table(dir.path(), &baker, before.as_ref(), &only, small, None)?;
        print_load("at end");
        return Ok(());
    }

    println!("\n### Level size (60 obstacles, 12 lights, falloff size/12, normal)\n");
    header();
    let mut by_size = Vec::new();
    for size in [128usize, 256, 512, 1024, 2048] {
        if size > max {
            break;
        }
        let r = baker
            .bake(
                dir.path(),
                &synth::bench_obstacles(size, 60, 12, 7),
                "normal",
            )?
            .run()?;
        row("obstacles", size, &r);
        by_size.push((size, r));
    }
    println!("\nScaling per 4x pixels (process time, gather time):");
    for w in by_size.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        println!(
            "- {} -> {}: process x{:.2}, CPU x{:.2}, gather x{:.2}, F x{:.2}",
            a.0,
            b.0,
            b.1.wall / a.1.wall,
            b.1.cpu.unwrap_or(f64::NAN) / a.1.cpu.unwrap_or(f64::NAN),
            stage(&b.1, "gather") / stage(&a.1, "gather"),
            stage(&b.1, "form_factors") / stage(&a.1, "form_factors").max(1e-9),
        );
    }

    println!("\n### Edge count (512 px, 12 lights, normal)\n");
    header();
    let mut by_edges = Vec::new();
    for obstacles in [15usize, 30, 60, 120, 240] {
        let r = baker
            .bake(
                dir.path(),
                &synth::bench_obstacles(512, obstacles, 12, 7),
                "normal",
            )?
            .run()?;
        row(&format!("{obstacles} obstacles"), 512, &r);
        by_edges.push(r);
    }
    let (first, last) = (&by_edges[0], &by_edges[by_edges.len() - 1]);
    println!(
        "\nEdges x{:.1}: gather x{:.2}, process x{:.2}, CPU x{:.2}",
        count(last, "edges") as f64 / count(first, "edges") as f64,
        stage(last, "gather") / stage(first, "gather"),
        last.wall / first.wall,
        last.cpu.unwrap_or(f64::NAN) / first.cpu.unwrap_or(f64::NAN)
    );

    println!("\n### Patch count (512 px, 60 obstacles)\n");
    header();
    for q in ["draft", "normal", "high"] {
        let r = baker
            .bake(dir.path(), &synth::bench_obstacles(512, 60, 12, 7), q)?
            .run()?;
        row(q, 512, &r);
    }

    println!(
        "\n### Naive against fast gather (40 one-pixel walls, 3 lights, no falloff, normal)\n"
    );
    println!(
        "Errors: RMS difference relative to the `reference` bake's RMS (patch 0.5 px, quadrature 8). The naive gather runs at 8 and at 64 sample points per patch; ratios are naive gather time over fast gather time, measured in this run.\n"
    );
    println!(
        "| level | fast gather s | fast err | naive (8) s | naive (8) err | naive (8) / fast | naive (64) s | naive (64) err | naive (64) / fast |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for size in [32usize, 64, 128] {
        if quick && size > 64 {
            break;
        }
        let (lv, _) = load_level(&synth::bench_scattered(size, 40, 3, 7))?;
        let (reference, _) = bake_floor_at(&lv, Quality::Reference, GatherMethod::Fast, 8)?;
        // Warm-up, then the best of three for the fast gather (it is short).
        let _ = bake_floor(&lv, GatherMethod::Fast, 8)?;
        let mut fast_t = f64::INFINITY;
        let mut fast = Vec::new();
        for _ in 0..3 {
            let (v, t) = bake_floor(&lv, GatherMethod::Fast, 8)?;
            fast_t = fast_t.min(t);
            fast = v;
        }
        let err = |v: &[f32]| 100.0 * rel_err(v, &reference).0;
        let (naive8, t8) = bake_floor(&lv, GatherMethod::Naive, 8)?;
        let (naive64, t64) = bake_floor(&lv, GatherMethod::Naive, 64)?;
        println!(
            "| scattered {size}x{size} | {fast_t:.4} | {:.3}% | {t8:.3} | {:.3}% | {:.0} | {t64:.2} | {:.3}% | {:.0} |",
            err(&fast),
            err(&naive8),
            t8 / fast_t,
            err(&naive64),
            t64 / fast_t,
        );
    }
    classes_table(
        dir.path(),
        &baker,
        before.as_ref(),
        &only,
        small,
        quick.then_some(1 << 20),
    )?;
    println!();
    print_load("at end");
    Ok(())
}
