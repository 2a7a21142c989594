//! `tetvr bench`: picks scenes and configurations from the arguments, runs them with a
//! progress bar, and writes the CSV, the skipped list and the plots.

use std::path::Path;
use std::time::Instant;

use crate::bench::{
    self, BenchError, Environment, ON_REQUEST_SCENES, Options, Plan, QUICK_SCENES,
    cache::ReferenceCache, plot,
};
use indicatif::{ProgressBar, ProgressStyle};
use tetvr::gpu::{AdapterChoice, GpuContext, GpuError};
use tetvr::scene::Scene;

use super::BenchArgs;
use super::commands::CliError;

impl From<BenchError> for CliError {
    fn from(e: BenchError) -> Self {
        Self::Bench(Box::new(e))
    }
}

pub fn bench(args: BenchArgs) -> Result<(), CliError> {
    let start = Instant::now();
    let configs = selected_configs(&args)?;
    let scenes = selected_scenes(&args)?;
    let ctx = open_gpu()?;
    let adapter = ctx
        .as_ref()
        .map_or_else(|| "no GPU adapter".to_string(), |c| c.summary());
    let env = Environment::detect(adapter);
    let plan = Plan {
        scenes,
        configs,
        size: args
            .size
            .unwrap_or(if args.quick { (128, 128) } else { (256, 256) }),
        data: args.data.clone(),
        options: Options {
            runs: args
                .runs
                .map_or(if args.quick { 3 } else { 5 }, |r| r as usize),
            warmup: 1,
        },
    };
    std::fs::create_dir_all(&args.out).map_err(|source| BenchError::Write {
        path: args.out.display().to_string(),
        source,
    })?;
    let mut cache = ReferenceCache::new(args.out.join("cache"));
    let bar = ProgressBar::new(plan.steps()).with_style(
        ProgressStyle::with_template("bench {bar:30} {pos}/{len} {elapsed} {msg}")
            .expect("a valid template"),
    );
    let report = bench::run(&plan, ctx.as_ref(), &mut cache, &mut |what, steps| {
        bar.set_message(what.to_string());
        bar.inc(steps);
    })?;
    bar.finish_and_clear();

    let written = write_outputs(&args.out, &report, &env)?;
    print!("{}", bench::table(&report.rows));
    print!("{}", bench::legend(&plan.options));
    for s in &report.skipped {
        println!(
            "skipped: {} {} {} ({}): {}",
            s.scene, s.view, s.mode, s.setting, s.reason
        );
    }
    println!("adapter: {}", env.adapter);
    println!("machine: {}", env.machine);
    println!(
        "reference images: {} from the cache, {} computed ({})",
        cache.hits,
        cache.misses,
        args.out.join("cache").display()
    );
    println!(
        "wrote {} in {:.1} s",
        written.join(", "),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The configurations `--modes` names (all without it); an unknown mode lists the known ones.
fn selected_configs(args: &BenchArgs) -> Result<Vec<bench::Config>, CliError> {
    let mut configs = bench::configurations(args.quick);
    let all_modes = bench::mode_names(&configs);
    if let Some(m) = args
        .modes
        .iter()
        .find(|m| !configs.iter().any(|c| c.mode == m.as_str()))
    {
        return Err(BenchError::UnknownMode(m.clone(), all_modes).into());
    }
    if !args.modes.is_empty() {
        configs.retain(|c| args.modes.iter().any(|m| m == c.mode));
    }
    Ok(configs)
}

/// The scenes `--scenes` names; without it, the quick ones with `--quick`, else every scene
/// but those run only on request. An unknown scene lists the known ones.
fn selected_scenes(args: &BenchArgs) -> Result<Vec<bench::SceneSpec>, CliError> {
    if let Some(path) = &args.scene {
        return Ok(vec![user_scene(path, args.size)?]);
    }
    let catalogue = bench::catalogue();
    if let Some(s) = args
        .scenes
        .iter()
        .find(|s| !catalogue.iter().any(|c| c.name == s.as_str()))
    {
        let names = catalogue
            .iter()
            .map(|s| s.name.as_str())
            .collect::<Vec<_>>();
        return Err(BenchError::UnknownScene(s.clone(), names.join(", ")).into());
    }
    let wanted = |name: &str| {
        if !args.scenes.is_empty() {
            args.scenes.iter().any(|s| s == name)
        } else if args.quick {
            QUICK_SCENES.contains(&name)
        } else {
            !ON_REQUEST_SCENES.contains(&name)
        }
    };
    Ok(catalogue.into_iter().filter(|s| wanted(&s.name)).collect())
}

/// The scene of the file at `path` at `size` (its own without), named as the file.
fn user_scene(path: &Path, size: Option<(u32, u32)>) -> Result<bench::SceneSpec, CliError> {
    let mut scene = Scene::load(path)?;
    if let Some((w, h)) = size {
        scene.size = [w, h];
    }
    let name = path
        .file_stem()
        .map_or("scene".into(), |s| s.to_string_lossy());
    Ok(bench::SceneSpec::user(name.into_owned(), scene))
}

/// The GPU the bench measures on, or `None` (said on stderr) without an adapter.
fn open_gpu() -> Result<Option<GpuContext>, CliError> {
    match GpuContext::new(AdapterChoice::from_env()) {
        Ok(ctx) => Ok(Some(ctx)),
        Err(GpuError::NoAdapter { .. }) => {
            eprintln!(
                "note: no GPU adapter (install mesa-vulkan-drivers for a software one); the bench runs the CPU modes only"
            );
            Ok(None)
        }
        Err(e) => Err(e.into()),
    }
}

/// Writes the CSV, one Pareto plot per scene and view, the scaling plot, and where they have
/// rows the skipped list and the skips table into `out`; returns the paths written.
fn write_outputs(
    out: &Path,
    report: &bench::Report,
    env: &Environment,
) -> Result<Vec<String>, CliError> {
    let csv = bench::csv_path(out);
    bench::write_csv(&csv, &report.rows, env)?;
    let mut written = vec![csv.display().to_string()];
    let mut pairs: Vec<(&str, &str)> = Vec::new();
    for r in &report.rows {
        if !pairs.contains(&(r.scene.as_str(), r.view)) {
            pairs.push((r.scene.as_str(), r.view));
        }
    }
    for (scene, view) in pairs {
        let path = out.join(format!("pareto-{scene}-{view}.svg"));
        plot::pareto(&path, &report.rows, scene, view, env)?;
        written.push(path.display().to_string());
    }
    let path = out.join("scaling.svg");
    plot::scaling(&path, &report.rows, env)?;
    written.push(path.display().to_string());
    if !report.skipped.is_empty() {
        let path = out.join("skipped.csv");
        bench::write_skipped(&path, &report.skipped)?;
        written.push(path.display().to_string());
    }
    let skips = bench::skips_table(&report.rows);
    if skips.lines().count() > 2 {
        let path = out.join("skips.md");
        std::fs::write(&path, &skips).map_err(|source| BenchError::Write {
            path: path.display().to_string(),
            source,
        })?;
        written.push(path.display().to_string());
    }
    Ok(written)
}
