//! `lancet render` on the command line: pictures of a cut (on a real device), and a clear error
//! without one.

use std::path::Path;
use std::process::Command;

fn lancet() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_lancet"));
    c.current_dir(crate::REPO);
    c
}

/// With the Vulkan driver hidden and only Vulkan searched, there is no adapter: the command
/// fails with exit code 2 and says rendering needs one, instead of panicking.
#[test]
fn without_an_adapter_the_error_says_rendering_needs_one() {
    let out = tempfile::tempdir().unwrap();
    let o = lancet()
        .args([
            "render",
            "fixtures/scenes/probe_press.ron",
            "--steps",
            "2",
            "--output",
        ])
        .arg(out.path())
        .env("VK_ICD_FILENAMES", "/nonexistent")
        .env("WGPU_BACKEND", "vulkan")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("rendering needs a GPU adapter"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// A blade cutting a box: `--frames 2` writes two pictures named after the series, the JSON summary lists them, and the tissue, the blade and the colour bar
/// are in them.
#[test]
fn render_writes_the_pictures_it_lists() {
    if crate::common::gpu().is_none() {
        return;
    }
    let out = tempfile::tempdir().unwrap();
    let o = lancet()
        .args([
            "render",
            "fixtures/scenes/cut_box_through.ron",
            "--steps",
            "200",
            "--frames",
            "2",
            "--width",
            "240",
            "--height",
            "180",
            "--method",
            "separate",
            "--json",
            "--output",
        ])
        .arg(out.path())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let pictures = v["pictures"].as_array().unwrap();
    assert_eq!(pictures.len(), 2, "{stdout}");
    let times: Vec<f64> = pictures
        .iter()
        .map(|p| p["time"].as_f64().unwrap())
        .collect();
    assert!(0.0 < times[0] && times[0] < times[1], "{times:?}");
    for p in pictures {
        let path = Path::new(p["path"].as_str().unwrap());
        assert!(path.starts_with(out.path()), "{}", path.display());
        assert!(path
            .file_name()
            .unwrap()
            .to_str()
            .unwrap()
            .starts_with("cut_box_through__"));
        let image = lancet::render::png_out::read_png(path).unwrap();
        assert_eq!((image.width, image.height), (240, 180));
        let coverage = p["coverage"].as_f64().unwrap();
        assert!(coverage > 0.05 && coverage < 0.9, "{coverage}");
        // The colour bar's top is viridis' yellow.
        let [x0, x1, y0, _] = lancet::render::png_out::legend_rect(240, 180);
        let top = image.pixel((x0 + x1) / 2, y0 + 2);
        assert!(top[0] > 200 && top[1] > 180 && top[2] < 80, "{top:?}");
        // The blade's grey is somewhere in the picture.
        let grey = image
            .rgba
            .chunks_exact(4)
            .filter(|p| {
                let (r, g, b) = (p[0] as i32, p[1] as i32, p[2] as i32);
                (b - r) > 3 && (b - r) < 30 && (g - r).abs() < 15 && r > 40 && r < 200
            })
            .count();
        assert!(grey > 20, "blade pixels: {grey}");
    }
}
