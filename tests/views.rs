//! The 3D pages of the binary: `fk|ik|analyze --view FILE.html` and `workspace.html`,
//! self-contained (plotly inlined, nothing fetched) and holding the expected layers.
//! The browser check (they render without console errors) is tests/browser/run.sh.

mod common;

use std::path::Path;
use std::process::{Command, Output};

use common::design_path;

fn tdpcr(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tdpcr"))
        .args(args)
        .output()
        .expect("binary runs")
}

fn design() -> String {
    design_path("lilge2022.ron").display().to_string()
}

/// The figure JSON of a page.
fn figure(path: &Path) -> serde_json::Value {
    let page = std::fs::read_to_string(path).unwrap();
    assert!(page.contains("plotly.js v3.3.0"), "plotly inlined");
    assert!(!page.contains("<script src"), "nothing fetched");
    let start = page.find("const figure = ").unwrap() + "const figure = ".len();
    let end = page[start..].find(";\nPlotly").unwrap() + start;
    serde_json::from_str(&page[start..end]).unwrap()
}

fn names(fig: &serde_json::Value) -> Vec<String> {
    fig["data"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|t| t["name"].as_str().map(String::from))
        .collect()
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("tdpcr-views-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn fk_ik_and_analyze_write_a_page_of_the_configuration() {
    let dir = temp_dir("config");
    let q = "0.004,0.02,-0.003,-0.01,0.002,0.03";
    let fk = dir.join("fk.html");
    let o = tdpcr(&["fk", &design(), "--q", q, "--view", fk.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let n = names(&figure(&fk));
    for layer in [
        "legs (backbone)",
        "disks",
        "bases (actuated)",
        "platform",
        "gravity",
    ] {
        assert!(n.iter().any(|x| x == layer), "{layer} missing in {n:?}");
    }
    assert!(n.iter().any(|x| x.starts_with("tendons, taut")));
    assert!(
        !n.iter().any(|x| x.contains("ellipsoid")),
        "fk has no ellipsoids"
    );

    let ik = dir.join("ik.html");
    let o = tdpcr(&[
        "ik",
        &design(),
        "--position",
        "0.01,0.02,0",
        "--view",
        ik.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let fig = figure(&ik);
    assert!(
        fig["layout"]["title"]["text"]
            .as_str()
            .unwrap()
            .contains("(10.00, 20.00, 0.00) mm")
    );

    let an = dir.join("analyze.html");
    let o = tdpcr(&[
        "analyze",
        &design(),
        "--q",
        q,
        "--view",
        an.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let n = names(&figure(&an));
    assert!(
        n.iter()
            .any(|x| x.starts_with("J_p ellipsoid (1 m/m drawn as")),
        "{n:?}"
    );
    assert!(
        n.iter()
            .any(|x| x.starts_with("C_p ellipsoid (1 m/N drawn as")),
        "{n:?}"
    );
    // Only the pages: no temporary file left behind.
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    files.sort();
    assert_eq!(files, ["analyze.html", "fk.html", "ik.html"]);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn an_unwritable_view_exits_2_naming_the_file() {
    let bad = temp_dir("bad").join("missing").join("v.html");
    let o = tdpcr(&[
        "fk",
        &design(),
        "--q",
        "0,0,0,0,0,0",
        "--view",
        bad.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("cannot write") && err.contains("v.html"),
        "{err}"
    );
    assert!(!bad.exists());
}

#[test]
fn workspace_writes_a_page_of_its_cells_with_the_home_configuration() {
    let out = temp_dir("ws").join("out");
    let o = tdpcr(&[
        "workspace",
        &design(),
        "--step",
        "0.01",
        "--angle-step",
        "1.0",
        "--z-range",
        "-0.01,0.0",
        "--threads",
        "2",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("workspace.html"), "{stdout}");
    let fig = figure(&out.join("workspace.html"));
    let cloud = &fig["data"][0];
    assert_eq!(cloud["name"], "reachable cells");
    // One point per reachable row of points.csv, at the cell centres (multiples of 10 mm).
    let csv = std::fs::read_to_string(out.join("points.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let reachable = csv
        .lines()
        .skip(1)
        .filter(|l| {
            let f: Vec<&str> = l.split(',').collect();
            f[col("collision")] == "0" && f[col("unstable")] == "0"
        })
        .count();
    let x = cloud["x"].as_array().unwrap();
    assert_eq!(x.len(), reachable);
    assert!(
        x.iter()
            .all(|v| (v.as_f64().unwrap() / 10.0).fract() == 0.0)
    );
    let menu = &fig["layout"]["updatemenus"][0]["buttons"];
    let labels: Vec<&str> = menu
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b["label"].as_str().unwrap())
        .collect();
    assert_eq!(labels.len(), 5, "{labels:?}");
    assert_eq!(
        menu[4]["args"][0]["marker.color"][0]
            .as_array()
            .unwrap()
            .len(),
        reachable
    );
    let n = names(&fig);
    assert!(n.iter().any(|x| x == "home: legs (backbone)"), "{n:?}");
    assert!(
        n.iter()
            .any(|x| x.starts_with("near Type II singularity ("))
    );
    std::fs::remove_dir_all(out.parent().unwrap()).ok();
}

#[test]
fn analyze_plot_also_draws_the_configuration_in_three_views() {
    let dir = temp_dir("sketch");
    let o = tdpcr(&[
        "analyze",
        &design(),
        "--q",
        "0.004,0.02,-0.003,-0.01,0.002,0.03",
        "--plot",
        dir.to_str().unwrap(),
        "--format",
        "json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let path = dir.join("configuration.svg");
    assert_eq!(v["configuration_plot"], path.to_str().unwrap());
    assert_eq!(
        v["plots"].as_array().unwrap().len(),
        4,
        "the ellipsoid plots as before"
    );
    let svg = std::fs::read_to_string(&path).unwrap();
    assert!(svg.starts_with("<svg"));
    for view in ["top (xy)", "front (xz)", "side (yz)", "x [mm]", "z [mm]"] {
        assert!(svg.contains(view), "{view}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn fk_and_ik_plot_write_the_configuration_in_three_views() {
    for (kind, target, value) in [
        ("fk", "--q", "0.004,0.02,-0.003,-0.01,0.002,0.03"),
        ("ik", "--position", "0.01,-0.005,0.02"),
    ] {
        // A directory that does not exist yet: created.
        let dir = temp_dir(&format!("sketch-{kind}")).join("figures");
        let o = tdpcr(&[
            kind,
            &design(),
            target,
            value,
            "--plot",
            dir.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let svg = std::fs::read_to_string(dir.join("configuration.svg")).unwrap();
        assert!(svg.starts_with("<svg"), "{kind}");
        for view in ["top (xy)", "front (xz)", "side (yz)"] {
            assert!(svg.contains(view), "{kind}: {view}");
        }
        std::fs::remove_dir_all(dir.parent().unwrap()).ok();
    }
}
