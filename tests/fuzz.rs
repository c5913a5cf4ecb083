//! Fuzz corpus (issue 14, deliverable 4): property tests over the bundled design files
//! (every numeric field perturbed to extreme, non-finite, negative, huge and zero values;
//! the raw text mutated), the CLI's numeric flags of every subcommand and the CSV rows of
//! `trajectory`. Asserted: no panic, no NaN in any output, every error names its input,
//! bounded time. Cases that ever failed are kept by proptest in
//! `tests/fuzz.proptest-regressions` and replayed first on every run.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use proptest::prelude::*;
use proptest::sample::select;

use tdpcr::tdcr::{TdcrSolver, TendonControl, TipWrench};
use tdpcr::{Solver, Tdcr, Tdpcr, Wrench};

/// The bundled designs: (file name, text, is a `Tdpcr`).
fn designs() -> Vec<(String, String, bool)> {
    let mut out = Vec::new();
    for dir in ["designs", "designs/optimized"] {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join(dir);
        let mut names: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "ron"))
            .collect();
        names.sort();
        for p in names {
            let text = std::fs::read_to_string(&p).unwrap();
            let parallel = text.contains("Tdpcr(");
            out.push((p.display().to_string(), text, parallel));
        }
    }
    out
}

/// A design's canonical text (`to_ron_string` of the parsed file): one value per field,
/// no comments.
fn canonical(text: &str, parallel: bool) -> String {
    if parallel {
        Tdpcr::from_ron_str(text, "design").unwrap().to_ron_string()
    } else {
        Tdcr::from_ron_str(text, "design").unwrap().to_ron_string()
    }
}

/// Byte ranges of the numeric literals of `text`, each with the field name nearest
/// before it (`length`, `gravity`, `coupling_angles`, ...).
fn numeric_fields(text: &str) -> Vec<(std::ops::Range<usize>, String)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts_number = (b[i].is_ascii_digit() || b[i] == b'-')
            && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_'));
        if starts_number {
            let start = i;
            i += 1;
            while i < b.len()
                && (b[i].is_ascii_alphanumeric() || matches!(b[i], b'.' | b'-' | b'+'))
            {
                i += 1;
            }
            let key = text[..start]
                .rfind(':')
                .map(|c| {
                    let before = text[..c].trim_end();
                    let k0 = before
                        .rfind(|ch: char| !(ch.is_ascii_alphanumeric() || ch == '_'))
                        .map_or(0, |k| k + 1);
                    before[k0..].to_string()
                })
                .unwrap_or_default();
            out.push((start..i, key));
        } else {
            i += 1;
        }
    }
    out
}

/// Extreme values a field may be given.
fn extreme() -> impl Strategy<Value = String> {
    prop_oneof![
        select(vec![
            "NaN",
            "inf",
            "-inf",
            "0",
            "-0",
            "0.0",
            "-0.0",
            "-1",
            "-1.0",
            "1e308",
            "-1e308",
            "1e-308",
            "5e-324",
            "1e30",
            "-1e30",
            "4294967296",
            "18446744073709551615",
            "99999999999999999999999",
            "1e6",
            "1",
            "2",
            "100000",
            "3.2e1",
        ])
        .prop_map(str::to_string),
        any::<f64>().prop_map(|x| format!("{x:?}")),
        (-1e3f64..1e3).prop_map(|x| format!("{x:?}")),
    ]
}

/// The first line (1-based) of byte offset `at` in `text`.
fn line_of(text: &str, at: usize) -> usize {
    text[..at].matches('\n').count() + 1
}

/// Loads `text` as the design kind; `Ok(None)` when it loads, `Err(message)` otherwise.
fn load(text: &str, parallel: bool) -> Result<(), String> {
    if parallel {
        Tdpcr::from_ron_str(text, "fuzz.ron")
            .map(drop)
            .map_err(|e| e.to_string())
    } else {
        Tdcr::from_ron_str(text, "fuzz.ron")
            .map(drop)
            .map_err(|e| e.to_string())
    }
}

/// An error names a perturbed field: by its name (validation) or by its line (parse).
fn names_a_field(message: &str, fields: &[(String, usize)]) -> bool {
    fields.iter().any(|(key, line)| {
        message.contains(key.as_str()) || message.contains(&format!("fuzz.ron:{line}:"))
    })
}

/// FK at q = 0 and one small FK (or a tension and a displacement solve of a TDCR): each
/// returns Ok with finite outputs or a typed error, in bounded time.
fn solves_stay_finite(text: &str, parallel: bool) -> Result<(), TestCaseError> {
    let start = Instant::now();
    if parallel {
        let design = Tdpcr::from_ron_str(text, "fuzz.ron").unwrap();
        let mut solver = match Solver::new(&design) {
            Ok(s) => s,
            Err(_) => return Ok(()),
        };
        let n = design.n_actuators();
        for q in [
            vec![0.0; n],
            (0..n).map(|i| 1e-3 * (i % 3) as f64).collect(),
        ] {
            if let Ok(sol) = solver.solve_fk(&q, &Wrench::default(), None) {
                let shown = format!("{sol:?}");
                prop_assert!(!has_non_finite(&shown), "FK {q:?} gave {shown}");
            }
        }
    } else {
        let robot = Tdcr::from_ron_str(text, "fuzz.ron").unwrap();
        let nt = robot.leg.tendons.len();
        let mut solver = TdcrSolver::new(&robot);
        let mut tensions = vec![0.0; nt];
        tensions[0] = 0.5;
        for control in [
            TendonControl::Tension(vec![0.0; nt]),
            TendonControl::Tension(tensions),
            TendonControl::Displacement(vec![-1e-4; nt]),
        ] {
            if let Ok(sol) = solver.solve(&control, &TipWrench::default(), None) {
                let shown = format!("{sol:?}");
                prop_assert!(!has_non_finite(&shown), "{control:?} gave {shown}");
            }
        }
    }
    prop_assert!(
        start.elapsed() < Duration::from_secs(20),
        "solves took {:?}",
        start.elapsed()
    );
    Ok(())
}

/// Whether `text` shows a non-finite number (a `NaN` or `inf` word).
fn has_non_finite(text: &str) -> bool {
    text.split(|c: char| !c.is_ascii_alphanumeric())
        .any(|w| w.eq_ignore_ascii_case("nan") || w.eq_ignore_ascii_case("inf"))
}

/// One design with 1 to 3 of its numeric fields replaced by extreme values.
fn perturbed_design() -> impl Strategy<Value = (String, bool, Vec<(String, usize)>)> {
    let designs = designs();
    (
        0..designs.len(),
        prop::collection::vec((any::<prop::sample::Index>(), extreme()), 1..=3),
    )
        .prop_map(move |(d, edits)| {
            let (_, text, parallel) = &designs[d];
            let mut text = canonical(text, *parallel);
            let mut fields = Vec::new();
            for (at, value) in edits {
                let numbers = numeric_fields(&text);
                let (range, key) = numbers[at.index(numbers.len())].clone();
                fields.push((key, line_of(&text, range.start)));
                text.replace_range(range, &value);
            }
            (text, *parallel, fields)
        })
}

/// `cases` cases from a fixed seed: CI runs the same corpus every time (the saved
/// regressions in `fuzz.proptest-regressions` run first); change the seed to explore.
fn config(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases,
        rng_seed: proptest::test_runner::RngSeed::Fixed(20261125),
        ..ProptestConfig::default()
    }
}

proptest! {
    #![proptest_config(config(1200))]

    /// A design with perturbed fields loads, or fails naming a perturbed field; through
    /// the struct (`to_ron_string` of what deserializes) it gives the same verdict.
    #[test]
    fn perturbed_design_fields_load_or_name_the_field(
        (text, parallel, fields) in perturbed_design()
    ) {
        let direct = load(&text, parallel);
        if let Err(message) = &direct {
            prop_assert!(names_a_field(message, &fields), "{message}\nfields {fields:?}\n{text}");
        }
        // The same values through the struct and its serializer.
        let reserialized = if parallel {
            ron::from_str::<Tdpcr>(&text).ok().map(|d| d.to_ron_string())
        } else {
            ron::from_str::<Tdcr>(&text).ok().map(|d| d.to_ron_string())
        };
        if let Some(again) = reserialized {
            let through = load(&again, parallel);
            prop_assert_eq!(through.is_ok(), direct.is_ok(), "{:?}\n{}", through, again);
        }
    }
}

proptest! {
    #![proptest_config(config(1000))]

    /// Raw text mutations (bytes deleted, duplicated or inserted): never a panic.
    #[test]
    fn mutated_design_text_never_panics(
        d in 0..designs().len(),
        edits in prop::collection::vec(
            (any::<prop::sample::Index>(), 0usize..4, select(vec![
                "", "(", ")", "[", "]", ",", ":", "\"", "-", "e", "NaN", "inf", "9", "Some(",
                "r#", "/*", "\u{0}", "é", "count: 4294967296",
            ])),
            1..4,
        )
    ) {
        let all = designs();
        let (_, text, parallel) = &all[d];
        let mut text = text.clone();
        for (at, len, insert) in edits {
            let mut i = at.index(text.len() + 1);
            while !text.is_char_boundary(i) {
                i -= 1;
            }
            let mut j = (i + len).min(text.len());
            while !text.is_char_boundary(j) {
                j += 1;
            }
            text.replace_range(i..j, insert);
        }
        let _ = load(&text, *parallel);
    }
}

proptest! {
    #![proptest_config(config(150))]

    /// A perturbed design that loads solves (FK at q = 0 and near it) to finite outputs
    /// or a typed error, in bounded time.
    #[test]
    fn loadable_perturbed_designs_solve_or_fail_typed(
        (text, parallel, _) in perturbed_design()
    ) {
        if load(&text, parallel).is_ok() {
            solves_stay_finite(&text, parallel)?;
        }
    }
}

// ---- the binary -------------------------------------------------------------------

/// Runs the binary with a time limit; the child is killed (and the case fails) past it.
fn tdpcr(args: &[String]) -> Result<Output, TestCaseError> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_tdpcr"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("binary starts");
    let start = Instant::now();
    loop {
        if child.try_wait().expect("wait").is_some() {
            return Ok(child.wait_with_output().expect("output"));
        }
        if start.elapsed() > Duration::from_secs(30) {
            let _ = child.kill();
            let _ = child.wait();
            return Err(TestCaseError::fail(format!("tdpcr {args:?} ran past 30 s")));
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Exit code 0, 1 or 2, no panic, no NaN or infinity on stdout.
fn check_exit(args: &[String], o: &Output) -> Result<(), TestCaseError> {
    let stderr = String::from_utf8_lossy(&o.stderr);
    let stdout = String::from_utf8_lossy(&o.stdout);
    prop_assert!(
        matches!(o.status.code(), Some(0..=2)),
        "tdpcr {args:?}: exit {:?}\n{stderr}",
        o.status
    );
    prop_assert!(!stderr.contains("panicked"), "tdpcr {args:?}: {stderr}");
    // Values only: an error's text (`error` of the JSON) may quote a non-finite residual.
    let values = match serde_json::from_str::<serde_json::Value>(&stdout) {
        Ok(mut v) => {
            if let Some(m) = v.as_object_mut() {
                m.remove("error");
            }
            v.to_string()
        }
        Err(_) => stdout.to_string(),
    };
    prop_assert!(!has_non_finite(&values), "tdpcr {args:?}: {stdout}");
    if o.status.code() != Some(0) {
        prop_assert!(
            stderr.contains("error"),
            "tdpcr {args:?}: no error text: {stderr}"
        );
    }
    Ok(())
}

/// One fuzzed number as the user may type it.
fn number() -> impl Strategy<Value = String> {
    prop_oneof![
        3 => select(vec![
            "NaN", "nan", "inf", "-inf", "infinity", "-0", "0", "1e308", "-1e308", "1e-308",
            "", " ", "abc", "0x10", "1e", "--", "1e6", "-1e6", "0.001", "-0.001", "0.01",
            "1", "100",
        ])
        .prop_map(str::to_string),
        1 => (-1e-2f64..1e-2).prop_map(|x| format!("{x}")),
        1 => any::<f64>().prop_map(|x| format!("{x:e}")),
    ]
}

/// A comma-separated list of `n` fuzzed numbers, or a wrong count of them.
fn list(n: usize) -> impl Strategy<Value = String> {
    prop_oneof![
        3 => prop::collection::vec(number(), n..=n),
        1 => prop::collection::vec(number(), 0..12),
    ]
    .prop_map(|v| v.join(","))
}

fn path_of(name: &str) -> String {
    common::design_path(name).display().to_string()
}

/// The argument lists of every subcommand with fuzzed numeric values.
fn cli_case() -> impl Strategy<Value = Vec<String>> {
    let format = select(vec!["text", "json"]);
    let design = select(vec!["lilge2022.ron", "lilge2022_redundant.ron"]);
    let s = |x: &str| x.to_string();
    prop_oneof![
        (list(2), list(3), list(3), number(), format.clone()).prop_map(
            move |(t, f, m, tol, fmt)| vec![
                s("tdcr"),
                path_of("tdcr_one_segment.ron"),
                s("--tensions"),
                t,
                s("--tip-force"),
                f,
                s("--tip-moment"),
                m,
                s("--tolerance"),
                tol,
                s("--format"),
                s(fmt),
            ]
        ),
        (list(2), number(), format.clone()).prop_map(move |(d, n, fmt)| vec![
            s("tdcr"),
            path_of("tdcr_one_segment.ron"),
            s("--displacements"),
            d,
            s("--max-iterations"),
            n,
            s("--format"),
            s(fmt),
        ]),
        (design.clone(), list(6), list(6), number(), format.clone()).prop_map(
            move |(d, q, w, tol, fmt)| vec![
                s("fk"),
                path_of(d),
                s("--q"),
                q,
                s("--wrench"),
                w,
                s("--tolerance"),
                tol,
                s("--format"),
                s(fmt),
            ]
        ),
        (
            design.clone(),
            list(3),
            list(3),
            number(),
            format.clone(),
            limits(),
            prop::option::of(list(9)),
        )
            .prop_map(move |(d, p, r, tol, fmt, lim, reference)| {
                let mut args = vec![
                    s("ik"),
                    path_of(d),
                    s("--position"),
                    p,
                    s("--rotvec"),
                    r,
                    s("--tolerance"),
                    tol,
                    s("--format"),
                    s(fmt),
                    s("--limits"),
                    s(lim),
                ];
                if let Some(reference) = reference {
                    args.extend([s("--reference"), reference]);
                }
                args
            }),
        (list(6), number(), format.clone()).prop_map(move |(q, th, fmt)| vec![
            s("analyze"),
            path_of("lilge2022.ron"),
            s("--q"),
            q,
            s("--type-ii-threshold"),
            th,
            s("--format"),
            s(fmt),
        ]),
        (list(3), list(3), format.clone()).prop_map(move |(p, r, fmt)| vec![
            s("analyze"),
            path_of("lilge2022.ron"),
            s("--position"),
            p,
            s("--rotvec"),
            r,
            s("--format"),
            s(fmt),
        ]),
        (number(), number(), format.clone()).prop_map(move |(n, seed, fmt)| vec![
            s("jacobian-check"),
            path_of("tdcr_one_segment.ron").replace("tdcr_one_segment", "lilge2022"),
            s("--samples"),
            n.chars().take(1).collect(),
            s("--seed"),
            seed,
            s("--format"),
            s(fmt),
        ]),
        (
            workspace_step(),
            workspace_angle(),
            list(2),
            list(3),
            limits()
        )
            .prop_map(move |(st, an, z, r, lim)| vec![
                s("workspace"),
                path_of("lilge2022.ron"),
                s("--limits"),
                s(lim),
                s("--step"),
                st,
                s("--angle-step"),
                an,
                s("--z-range"),
                z,
                s("--rotvec"),
                r,
                s("--threads"),
                s("1"),
                s("--out"),
                std::env::temp_dir()
                    .join(format!("tdpcr-fuzz-ws-{}", std::process::id()))
                    .display()
                    .to_string(),
            ]),
        Just(vec![s("validate"), path_of("lilge2022.ron")]),
    ]
}

/// `--limits` values: both valid ones and an invalid one.
fn limits() -> impl Strategy<Value = &'static str> {
    select(vec!["free", "strict", "loose"])
}

/// Workspace steps: every invalid kind, and valid ones coarse enough to finish quickly.
fn workspace_step() -> impl Strategy<Value = String> {
    prop_oneof![
        select(vec![
            "NaN", "inf", "-inf", "0", "-0", "-0.02", "1e308", "", "abc", "1e-6"
        ])
        .prop_map(str::to_string),
        (0.03f64..1.0).prop_map(|x| format!("{x}")),
    ]
}

fn workspace_angle() -> impl Strategy<Value = String> {
    prop_oneof![
        select(vec![
            "NaN", "inf", "-inf", "0", "-0", "-1", "1e308", "", "abc", "1e-5"
        ])
        .prop_map(str::to_string),
        (0.8f64..std::f64::consts::PI).prop_map(|x| format!("{x}")),
    ]
}

proptest! {
    #![proptest_config(config(260))]

    /// Every subcommand with fuzzed numeric flags: exit 0, 1 or 2, never a panic, no NaN
    /// on stdout, an error message on failure.
    #[test]
    fn cli_numeric_flags_exit_cleanly(args in cli_case()) {
        let o = tdpcr(&args)?;
        check_exit(&args, &o)?;
    }
}

/// A fuzzed CSV row of `trajectory`: numbers, wrong widths, NaN, garbage.
fn csv_rows(width: usize) -> impl Strategy<Value = String> {
    let row = prop_oneof![
        4 => prop::collection::vec((-2e-2f64..2e-2).prop_map(|x| format!("{x}")), width..=width),
        2 => prop::collection::vec(number(), width..=width),
        1 => prop::collection::vec(number(), 0..10),
        1 => select(vec!["# comment", "", "x,y,z,rx,ry,rz", ",,,,,", "\u{feff}0,0,0,0,0,0"])
            .prop_map(|s| vec![s.to_string()]),
    ]
    .prop_map(|v| v.join(","));
    prop::collection::vec(row, 0..6).prop_map(|rows| rows.join("\n"))
}

proptest! {
    #![proptest_config(config(100))]

    /// `trajectory --ik/--fk --limits` over fuzzed CSV rows: exit 0, 1 or 2, no panic, no
    /// NaN.
    #[test]
    fn trajectory_csv_rows_exit_cleanly(
        ik in any::<bool>(),
        rows in csv_rows(6),
        format in select(vec!["text", "json"]),
        lim in limits(),
    ) {
        let dir = std::env::temp_dir().join(format!("tdpcr-fuzz-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let csv = dir.join("rows.csv");
        std::fs::write(&csv, &rows).unwrap();
        let args: Vec<String> = vec![
            "trajectory".into(),
            path_of("lilge2022.ron"),
            if ik { "--ik" } else { "--fk" }.into(),
            csv.display().to_string(),
            "--format".into(),
            format.into(),
            "--limits".into(),
            lim.into(),
        ];
        let o = tdpcr(&args)?;
        check_exit(&args, &o)?;
    }
}
