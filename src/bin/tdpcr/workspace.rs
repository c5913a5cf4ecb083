//! `tdpcr workspace`: the translational workspace sweep for a fixed orientation, on a
//! thread pool, with a progress bar on a terminal; writes the map's files and its 3D
//! page `workspace.html`.

use std::io::IsTerminal;

use tdpcr::Tdpcr;
use tdpcr::error::Error;
use tdpcr::workspace::{CollisionPolicy, WorkspaceSettings, files, sweep_workspace_with_progress};

use crate::args::WorkspaceArgs;

/// The most threads `--threads` takes (the sweep's rays run on a pool of this size;
/// 5 000 threads took 23 s to start and stop on a 2-core machine).
const MAX_THREADS: usize = 1024;

/// Runs `tdpcr workspace`.
pub fn run(args: &WorkspaceArgs) -> Result<(), Error> {
    let design = Tdpcr::from_ron_file(&args.design)?;
    let n_actuators = tdpcr::model::Model::new(&design).n_actuators();
    let redundancy = args.redundancy.resolve(n_actuators)?;
    let mut v = tdpcr::error::Violations::default();
    let defaults = WorkspaceSettings::default();
    let z_range = match &args.z_range {
        None => defaults.z_range,
        Some(z) if z.0.len() == 2 => [z.0[0], z.0[1]],
        Some(z) => {
            v.push(
                "--z-range",
                tdpcr::error::counted(z.0.len(), "value"),
                "2 values ZMIN,ZMAX [m]",
            );
            defaults.z_range
        }
    };
    if let Some(n) = args.threads.filter(|n| !(1..=MAX_THREADS).contains(n)) {
        v.push("--threads", n, &format!("1 to {MAX_THREADS}"));
    }
    if !v.0.is_empty() {
        return Err(Error::Input(v));
    }
    let settings = WorkspaceSettings {
        rotvec: args.rotvec.unwrap_or_default().into(),
        step: args.step,
        angle_step: args.angle_step,
        z_range,
        collisions: if args.through_collisions {
            CollisionPolicy::Continue
        } else {
            CollisionPolicy::Stop
        },
        redundancy,
        one_sided_kinks: !args.two_sided_kinks,
        chord_contraction: args.chord_contraction,
        probe_iterations: args.probe_iterations,
        ..defaults
    };
    settings.validate().map_err(flag_names)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads.unwrap_or(0))
        .build()
        .map_err(|e| {
            let mut v = tdpcr::error::Violations::default();
            v.push(
                "--threads",
                args.threads.unwrap_or(0),
                &format!("a thread count the system allows ({e})"),
            );
            Error::Input(v)
        })?;
    let created = files::prepare_output_dir_created(
        &args.out,
        &["points.csv", "summary.json", "workspace.html"],
    )?;
    let bar = if std::io::stderr().is_terminal() {
        let bar = indicatif::ProgressBar::new(0);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{elapsed_precise} [{bar:40}] {pos}/{len} rays, ETA {eta}",
            )
            .expect("constant template"),
        );
        Some(bar)
    } else {
        None
    };
    let progress = |p: tdpcr::workspace::Progress| {
        if let Some(bar) = &bar {
            bar.set_length(p.rays_total as u64);
            bar.set_position(p.rays_done as u64);
        }
    };
    let map = pool
        .install(|| sweep_workspace_with_progress(&design, &settings, &progress))
        // Nothing was written: the directories made for this run go (if still empty).
        .inspect_err(|_| files::remove_created_dirs(&created))?;
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    // The files and the 3D view side by side on the sweep's threads: from the end of the
    // reference design's Δ = 3 mm sweep to the exit 2.4–3.0 s before, 1.9–2.2 s after
    // (2 cores).
    let (written, view) = pool.install(|| {
        rayon::join(
            || files::write_outputs(&map, &args.out),
            || crate::view::write_workspace(&args.out, &design, &map),
        )
    });
    let mut written = written?;
    written.push(view?);
    let s = &map.summary;
    if s.path_ends == [tdpcr::workspace::PathEnd::InvalidHome; 2] {
        eprintln!(
            "warning: {}",
            s.first_error
                .as_deref()
                .unwrap_or("the home configuration is invalid")
        );
    }
    println!(
        "{} reachable cells ({:.3e} m³), {} near Type II, {} collision, {} unstable; planes z \
         {:.3}..{:.3} m",
        s.counts.reachable,
        s.volume.reachable,
        s.counts.near_type_ii,
        s.counts.collision,
        s.counts.unstable,
        s.z_reached[0],
        s.z_reached[1]
    );
    let t = &s.table_iii.per_sample.without_type_ii;
    println!(
        "Tab. III means over {} ray samples (near Type II excluded): rcond J_p {:.3}, J_o {:.3}, \
         C_p {:.3}, C_o {:.3}",
        s.table_iii.per_sample.without_type_ii_count,
        t.j_p.mean,
        t.j_o.mean,
        t.c_p.mean,
        t.c_o.mean
    );
    println!(
        "{} solves in {:.1} s on {} threads ({:.0} solves/s)",
        s.solves, s.wall_time_s, s.threads, s.solves_per_second
    );
    for path in written {
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// The settings' violations under the flags that set them (`step` as `--step`, …).
fn flag_names(e: Error) -> Error {
    const FLAGS: [(&str, &str); 7] = [
        ("rotvec", "--rotvec"),
        ("step", "--step"),
        ("angle_step", "--angle-step"),
        ("z_range", "--z-range"),
        ("chord_contraction", "--chord-contraction"),
        ("probe_iterations", "--probe-iterations"),
        ("redundancy.reference", "--reference"),
    ];
    match e {
        Error::Input(mut v) => {
            for violation in &mut v.0 {
                if let Some((_, flag)) = FLAGS.iter().find(|(f, _)| *f == violation.field) {
                    violation.field = (*flag).to_string();
                }
            }
            Error::Input(v)
        }
        e => e,
    }
}
