//! `tetvr bench`: picks scenes and configurations from the arguments, runs them with a
//! progress bar, and writes the CSV, the skipped list and the plots.

use std::time::Instant;

use crate::bench::{
    self, BenchError, Environment, ON_REQUEST_SCENES, Options, Plan, QUICK_SCENES,
    cache::ReferenceCache, plot,
};
use indicatif::{ProgressBar, ProgressStyle};
use tetvr::gpu::{AdapterChoice, GpuContext, GpuError};

use super::BenchArgs;
use super::commands::CliError;

impl From<BenchError> for CliError {
    fn from(e: BenchError) -> Self {
        Self::Bench(Box::new(e))
    }
}

pub fn bench(args: BenchArgs) -> Result<(), CliError> {
    let start = Instant::now();
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
    let catalogue = bench::catalogue();
    let names = catalogue
        .iter()
        .map(|s| s.name)
        .collect::<Vec<_>>()
        .join(", ");
    if let Some(s) = args
        .scenes
        .iter()
        .find(|s| !catalogue.iter().any(|c| c.name == s.as_str()))
    {
        return Err(BenchError::UnknownScene(s.clone(), names).into());
    }
    let wanted = |name: &str| {
        if args.scenes.is_empty() {
            if args.quick {
                QUICK_SCENES.contains(&name)
            } else {
                !ON_REQUEST_SCENES.contains(&name)
            }
        } else {
            args.scenes.iter().any(|s| s == name)
        }
    };
    let scenes = catalogue.into_iter().filter(|s| wanted(s.name)).collect();

    let ctx = match GpuContext::new(AdapterChoice::from_env()) {
        Ok(ctx) => Some(ctx),
        Err(GpuError::NoAdapter { .. }) => {
            eprintln!(
                "note: no GPU adapter (install mesa-vulkan-drivers for a software one); the bench runs the CPU modes only"
            );
            None
        }
        Err(e) => return Err(e.into()),
    };
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
            runs: args.runs.unwrap_or(if args.quick { 3 } else { 5 }),
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

    let csv = bench::csv_path(&args.out);
    bench::write_csv(&csv, &report.rows, &env)?;
    let mut written = vec![csv.display().to_string()];
    let mut pairs: Vec<(&str, &str)> = Vec::new();
    for r in &report.rows {
        if !pairs.contains(&(r.scene.as_str(), r.view)) {
            pairs.push((r.scene.as_str(), r.view));
        }
    }
    for (scene, view) in pairs {
        let path = args.out.join(format!("pareto-{scene}-{view}.svg"));
        plot::pareto(&path, &report.rows, scene, view, &env)?;
        written.push(path.display().to_string());
    }
    let path = args.out.join("scaling.svg");
    plot::scaling(&path, &report.rows, &env)?;
    written.push(path.display().to_string());
    if !report.skipped.is_empty() {
        let path = args.out.join("skipped.csv");
        bench::write_skipped(&path, &report.skipped)?;
        written.push(path.display().to_string());
    }

    let skips = bench::skips_table(&report.rows);
    if skips.lines().count() > 2 {
        let path = args.out.join("skips.md");
        std::fs::write(&path, &skips).map_err(|source| BenchError::Write {
            path: path.display().to_string(),
            source,
        })?;
        written.push(path.display().to_string());
    }
    print!("{}", bench::table(&report.rows));
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
