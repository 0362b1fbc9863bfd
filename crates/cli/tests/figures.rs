//! Figures: fonts are inputs like any other (regular, bounded, errors naming
//! `BRDF_BASIS_FONT` and the path, before any work), heatmap colour bars and a zero
//! BRDF said, not drawn as a blank figure (box-plot whiskers at the data and Fig. 4a/4b's
//! names, order and ticks are unit tests of the figures, `plot::tests`).

use crate::common::*;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// Runs `c`, killing it after `limit` (a hang is a failure, not a stuck test run).
fn run_within(mut c: Command, limit: Duration) -> Output {
    let mut child = c
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    let t = Instant::now();
    while child.try_wait().expect("wait").is_none() {
        if t.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("still running after {limit:?}: {c:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().expect("output")
}

fn plot_with_font(font: &str, out: &Path) -> Output {
    let mut c = bin();
    c.env("BRDF_BASIS_FONT", font)
        .args(["--quiet", "plot", "--material", "polished-gold", "--out"])
        .arg(out);
    run_within(c, Duration::from_secs(30))
}

fn err(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `BRDF_BASIS_FONT=/dev/zero` read forever; a missing or unusable font was ignored
/// without a word. Now each is an error naming the variable and the path, and nothing is
/// written.
#[test]
fn unusable_fonts_are_refused_naming_the_variable_and_path() {
    let d = tmp();
    let not_font = d.path().join("notes.ttf");
    std::fs::write(&not_font, b"these are not glyphs").expect("write");
    let huge = d.path().join("huge.ttf");
    std::fs::File::create(&huge)
        .and_then(|f| f.set_len(65 << 20))
        .expect("sparse file");
    let missing = d.path().join("nosuch.ttf");
    let cases = [
        ("/dev/zero".to_string(), "not a regular file"),
        (d.path().display().to_string(), "not a regular file"),
        (missing.display().to_string(), "No such file"),
        (
            not_font.display().to_string(),
            "not a TrueType or OpenType font",
        ),
        (huge.display().to_string(), "64 MiB"),
    ];
    for (i, (font, why)) in cases.iter().enumerate() {
        let out = d.path().join(format!("l{i}.svg"));
        let o = plot_with_font(font, &out);
        let e = err(&o);
        assert!(!o.status.success(), "{font}: accepted");
        assert!(
            e.contains(&format!("BRDF_BASIS_FONT={font}")),
            "{font}: {e}"
        );
        assert!(e.contains(why), "{font}: {e}");
        assert!(!e.contains("panicked"), "{e}");
        assert!(!out.exists(), "{font}: output written");
    }
}

/// `reproduce` and `render --heatmap` refuse an unusable font before any work.
#[test]
fn unusable_font_is_refused_before_reproduce_and_render_work() {
    let d = tmp();
    let out = d.path().join("r");
    let mut c = bin();
    c.env("BRDF_BASIS_FONT", "/dev/zero")
        .args([
            "--quiet",
            "--backend",
            "cpu",
            "reproduce",
            "--no-appearance",
            "--runs",
            "2",
            "--out",
        ])
        .arg(&out);
    let t = Instant::now();
    let o = run_within(c, Duration::from_secs(30));
    assert!(!o.status.success());
    assert!(err(&o).contains("BRDF_BASIS_FONT=/dev/zero"), "{}", err(&o));
    assert!(
        !out.exists(),
        "output directory created before the font check"
    );
    assert!(t.elapsed() < Duration::from_secs(20));

    let fits = d.path().join("f.json");
    let o = bin()
        .args(["--quiet", "--backend", "cpu", "fit", "--basis"])
        .args([
            "mirror-silver,matte-white-paint",
            "--targets",
            "polished-gold",
            "--json",
        ])
        .arg(&fits)
        .output()
        .expect("fit");
    assert!(o.status.success(), "{}", err(&o));
    let mut c = bin();
    c.env("BRDF_BASIS_FONT", d.path().join("nosuch.ttf"))
        .args([
            "--quiet",
            "--backend",
            "cpu",
            "render",
            "--material",
            "polished-gold",
        ])
        .args(["--size", "16", "--fit"])
        .arg(&fits)
        .arg("--out")
        .arg(d.path().join("g.exr"))
        .arg("--heatmap")
        .arg(d.path().join("h.png"));
    let o = run_within(c, Duration::from_secs(30));
    assert!(!o.status.success());
    assert!(err(&o).contains("nosuch.ttf"), "{}", err(&o));
    assert!(!d.path().join("h.png").exists() && !d.path().join("g.exr").exists());
}

/// A heatmap PNG carries its colour bar: wider than the render, with the viridis ends in
/// a column right of it.
#[test]
fn heatmap_png_has_a_colour_bar() {
    let d = tmp();
    let fits = d.path().join("f.json");
    let o = bin()
        .args(["--quiet", "--backend", "cpu", "fit", "--basis"])
        .args([
            "mirror-silver,matte-white-paint",
            "--targets",
            "polished-gold",
            "--json",
        ])
        .arg(&fits)
        .output()
        .expect("fit");
    assert!(o.status.success(), "{}", err(&o));
    let heat = d.path().join("h.png");
    let o = bin()
        .args([
            "--quiet",
            "--backend",
            "cpu",
            "render",
            "--material",
            "polished-gold",
        ])
        .args(["--size", "64", "--fit"])
        .arg(&fits)
        .arg("--out")
        .arg(d.path().join("g.exr"))
        .arg("--heatmap")
        .arg(&heat)
        .output()
        .expect("render");
    assert!(o.status.success(), "{}", err(&o));
    let img = image::open(&heat).expect("png").to_rgb8();
    assert!(
        img.width() > 64 + 20 && img.height() >= 64,
        "{:?}",
        img.dimensions()
    );
    // Somewhere right of the render: a column going from yellow (top) to purple (bottom).
    let yellow = (65..img.width()).any(|x| {
        (0..img.height()).any(|y| {
            let p = img.get_pixel(x, y).0;
            p[0] > 230 && p[1] > 210 && p[2] < 60
        })
    });
    let purple = (65..img.width()).any(|x| {
        (0..img.height()).any(|y| {
            let p = img.get_pixel(x, y).0;
            p[0] < 80 && p[1] < 20 && p[2] > 70 && p[2] < 100
        })
    });
    assert!(yellow && purple, "no colour bar right of the heatmap");
}

/// A material whose BRDF is zero everywhere is said to be so (a warning, and text in the
/// figure), not drawn as a blank plot that passes for a result.
#[test]
fn zero_material_lobe_plot_is_said_not_blank() {
    let d = tmp();
    let csv = d.path().join("z.csv");
    std::fs::write(
        &csv,
        "material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\nzero,0,0,0,0,0,0,0.5,10\nred,0.5,0,0,0.2,0.2,0.2,0.5,100\n",
    )
    .expect("write");
    let out = d.path().join("z.svg");
    let o = bin()
        .arg("plot")
        .arg(&csv)
        .args(["--material", "zero", "--angles", "0,45", "--out"])
        .arg(&out)
        .output()
        .expect("run");
    assert!(o.status.success(), "{}", err(&o));
    let e = err(&o);
    assert!(e.contains("warning") && e.contains("`zero` is 0"), "{e}");
    if with_text() {
        let svg = std::fs::read_to_string(&out).expect("svg");
        assert!(
            svg.contains("BRDF = 0 in this plane"),
            "no note in the figure"
        );
    }
}
