//! `lancet bench`, `bench collide` and `bench cut`: timings against the bandwidth floor.

use super::*;

/// Run the benchmark matrix and print it.
pub(crate) fn bench_collide(
    triangles: &[usize],
    tools: &[usize],
    repeats: usize,
    json: bool,
) -> lancet::Result<ExitCode> {
    let (device, rows) = lancet::report::collide_bench::run(triangles, tools, repeats.max(1))?;
    if json {
        let v = json!({ "device": device, "rows": rows });
        println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        return Ok(ExitCode::SUCCESS);
    }
    println!("gpu device: {device}");
    println!(
        "{:>9} {:>5} {:>9} {:>9} {:>9} {:>10} {:>9} {:>9} {:>9} {:>10} {:>8} {:>9} {:>9}",
        "triangles",
        "tools",
        "gpu ms",
        "cpu ms",
        "bvh ms",
        "candidates",
        "ratio",
        "self gpu",
        "self cpu",
        "self pairs",
        "narrow",
        "gpu p2f",
        "cpu p2f"
    );
    for r in &rows {
        println!(
            "{:>9} {:>5} {:>9.3} {:>9.3} {:>9.3} {:>10.1} {:>9.2e} {:>9.3} {:>9.3} {:>10} {:>8.2} {:>9.3} {:>9.3}",
            r.triangles,
            r.tools,
            r.gpu_tool_ms,
            r.cpu_tool_ms,
            r.bvh_tool_ms,
            r.candidates,
            r.culling_ratio,
            r.gpu_self_ms,
            r.cpu_self_ms,
            r.self_pairs,
            r.narrow_us_per_candidate,
            r.gpu_pose_to_force_ms,
            r.cpu_pose_to_force_ms
        );
    }
    println!(
        "gpu/cpu ms: median wall time of one tool cull, readback included; bvh: parry's BVH \
         refitted and queried instead (the baseline); ratio: candidates \
         over triangle-tool pairs; self: tissue against itself, margin 0.5 mm; narrow: parry \
         tool-triangle query, us per candidate; p2f: pose to force (cull, read back the \
         candidates' nodes, narrow phase, correction) for a 3 mm probe pressed 0.5 mm, ms"
    );
    Ok(ExitCode::SUCCESS)
}

/// Run the cut benchmark and print it.
pub(crate) fn bench_cut(
    bench: &lancet::report::cut_bench::CutBench,
    json: bool,
) -> lancet::Result<ExitCode> {
    let rows = bench.run()?;
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(&rows).unwrap_or_default()
        );
        return Ok(ExitCode::SUCCESS);
    }
    // The engine column holds the short label ("gpu-valence"); the adapter, whose name is long
    // and the same on every GPU row, is named once above the table.
    let (labels, devices) = engine_labels(rows.iter().map(|r| r.engine.as_str()));
    for d in devices {
        println!("gpu device: {d}");
    }
    let ew = labels.iter().map(|l| l.len()).max().unwrap_or(0).max(6);
    println!(
        "{:>7} {:>6} {:>9} {:<ew$} {:>4} {:>7} {:>7} {:>7} {:>6} {:>6} {:>5} {:>6} {:>6} {:>6} {:>6} {:>10} {:>7} {:>7} {:>5} {:>8} {:>9} {:>9} {:>5} {:>5} {:>6} {:>6} {:>6} {:>6}  slowest in",
        "tets", "len cm", "method", "engine", "cuts", "p50 ms", "p99 ms", "max ms", "read", "nodes",
        "ahead", "cut", "apply", "surf", "step", "bytes/cut", "% lay", "rebuilt", "grown", "nodes/cm2", "dt before",
        "dt after", "floor", "min q", "quiet0", "quiet1", "dev0", "dev1"
    );
    for (r, engine) in rows.iter().zip(&labels) {
        let (part, ms) = r.slowest.largest();
        let grew = if r.slowest.grew { " (grew)" } else { "" };
        println!(
            "{:>7} {:>6.1} {:>9} {:<ew$} {:>4} {:>7.3} {:>7.3} {:>7.3} {:>6.3} {:>6.0} {:>5} {:>6.3} {:>6.3} {:>6.3} {:>6.3} {:>10.0} {:>7.2} {:>7} {:>5} {:>8.1} {:>9.3e} {:>9.3e} {:>5} {:>5.3} {:>6.3} {:>6.3} {:>6} {:>6}  {part} {ms:.3}{grew}",
            r.tets,
            r.length * 100.0,
            r.method,
            engine,
            r.cuts,
            r.p50_ms,
            r.p99_ms,
            r.max_ms,
            r.read_ms,
            r.nodes_read,
            r.reads_ahead,
            r.cut_ms,
            r.apply_ms,
            r.surface_ms,
            r.step_ms,
            r.bytes_per_cut,
            100.0 * r.bytes_per_cut / r.layout_bytes.max(1) as f64,
            r.passes_rebuilt,
            r.buffers_grown,
            r.nodes_per_cm2,
            r.dt_before,
            r.dt_after,
            r.quality_floor,
            r.min_quality,
            r.quiet_step_before_ms,
            r.quiet_step_after_ms,
            optional_ms(r.quiet_device_before_ms),
            optional_ms(r.quiet_device_after_ms)
        );
    }
    println!(
        "p50/p99/max: latency of a cut event (read + cut + apply + surf), ms; read: positions \
         near the blade read back; nodes: how many; ahead: events whose read came with the step \
         before; cut: the cutter; apply: the engine patched; surf: the surface handed over; \
         step: the step before each event, waited for (not in the latency); % lay: bytes per \
         cut against the whole layout; rebuilt / grown: passes rebuilt, buffers grown; dt: \
         stable step before and after; min q: lowest tet quality after; quiet0/quiet1 \
         (dev0/dev1): median of {quiet} steps before the first incision and after the last, wall \
         (device) ms; \
         slowest in: the largest part of the slowest event",
        quiet = lancet::report::cut_bench::QUIET_STEPS
    );
    Ok(ExitCode::SUCCESS)
}

/// A time the engine may not measure, ms, for a table column: "-" where it does not.
pub(crate) fn optional_ms(ms: Option<f64>) -> String {
    ms.map_or_else(|| "-".to_string(), |ms| format!("{ms:.3}"))
}

/// Split engine names such as "gpu-valence on llvmpipe (LLVM 15.0.7, 256 bits)" into the short
/// labels for a table column and the distinct devices, in order of first appearance.
pub(crate) fn engine_labels<'a>(
    names: impl Iterator<Item = &'a str>,
) -> (Vec<&'a str>, Vec<&'a str>) {
    let mut labels = Vec::new();
    let mut devices: Vec<&str> = Vec::new();
    for name in names {
        let (label, device) = name.split_once(" on ").unwrap_or((name, ""));
        labels.push(label);
        if !device.is_empty() && !devices.contains(&device) {
            devices.push(device);
        }
    }
    (labels, devices)
}

/// The device's copy bandwidth, the floor of the GPU rows (asked for only when there are
/// some), where an adapter opens.
pub(crate) fn device_bandwidth() -> Option<lancet::report::device_copy::DeviceBandwidth> {
    let ctx = lancet::engine::gpu::GpuContext::new().ok()?;
    match lancet::report::device_copy::device_copy(&ctx) {
        Ok(d) => Some(d),
        Err(e) => {
            eprintln!("note: the device copy bandwidth was not measured ({e}); the gpu rows use the host's");
            None
        }
    }
}

pub(crate) fn bench(
    cubes: &[usize],
    files: &[PathBuf],
    opts: &lancet::report::bench::BenchOptions,
    split: lancet::mesh::generate::TetSplit,
    json: bool,
) -> lancet::Result<ExitCode> {
    use lancet::report::{bandwidth, bench};
    let named = !(cubes.is_empty() && files.is_empty());
    let mut meshes: Vec<bench::BenchMesh> = if named {
        cubes.iter().map(|&n| bench::BenchMesh::Cube(n)).collect()
    } else if opts.preset.is_some() {
        bench::Preset::meshes(split)
    } else {
        // With no mesh named, the two default cubes (about 1,300 and 20,000 nodes).
        vec![bench::BenchMesh::Cube(10), bench::BenchMesh::Cube(26)]
    };
    meshes.extend(files.iter().cloned().map(bench::BenchMesh::File));
    // 2^24 doubles per array (128 MiB): far beyond any cache, as STREAM requires.
    let bw = bandwidth::stream_triad(1 << 24, 5);
    let mut device_bw = None;
    let report = bench::run_bench(&meshes, opts, &bw, || {
        device_bw = device_bandwidth();
        device_bw.as_ref().map(|d| d.bytes_per_s)
    })?;
    if json {
        let v = json!({
            "bandwidth": bw,
            "device_bandwidth": device_bw,
            "rows": report.rows,
            "skipped": report.skipped
        });
        println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        return Ok(ExitCode::SUCCESS);
    }
    let rows = &report.rows;
    println!(
        "memory bandwidth (STREAM triad, {} threads): {:.1} GB/s",
        bw.threads,
        bw.bytes_per_s / 1e9
    );
    if let Some(d) = &device_bw {
        println!(
            "device copy bandwidth ({}, read + written, {} MiB arrays): {:.1} GB/s on {}; the \
             floor of the gpu rows",
            d.method,
            d.bytes >> 20,
            d.bytes_per_s / 1e9,
            d.device
        );
    }
    print_gpu_devices(rows.iter().map(|r| r.engine.as_str()));
    if let Some(r) = rows.first() {
        println!("force model: {}", r.force_model);
    }
    println!(
        "{:<14} {:>8} {:>9} {:<24} {:<9} {:>9} {:>6} {:>9} {:>8} {:>10} {:>8} {:>7} {:>9}",
        "mesh",
        "nodes",
        "springs",
        "engine",
        "order",
        "mem (MB)",
        "pad %",
        "ms/step",
        "gpu ms",
        "Mspring/s",
        "GB/s",
        "floor %",
        "error"
    );
    for r in rows {
        let mut engine = r
            .engine
            .split(" on ")
            .next()
            .unwrap_or(&r.engine)
            .to_string();
        // The engine name carries the atomic variants; say "gather" too, so that every edges
        // row names its variant.
        if r.accumulation.as_deref() == Some("gather") {
            engine.push_str("-gather");
        }
        let mesh = r.mesh.rsplit('/').next().unwrap_or(&r.mesh);
        println!(
            "{:<14} {:>8} {:>9} {:<24} {:<9} {:>9.2} {:>6.1} {:>9.3} {:>8} {:>10.1} {:>8.2} {:>7.1} {:>9.2e}",
            mesh,
            r.nodes,
            r.springs,
            engine,
            r.order.as_deref().unwrap_or("-"),
            r.memory_bytes as f64 / 1e6,
            r.padding_percent,
            r.ms_per_step,
            r.gpu_ms_per_step.map_or("-".into(), |g| format!("{g:.3}")),
            r.spring_evals_per_s / 1e6,
            r.achieved_bytes_per_s / 1e9,
            100.0 * r.floor_ratio,
            r.error_vs_reference
        );
    }
    // Implicit rows: the solver's iterations, and the time and bytes of one (GB/s above is then
    // per iteration where the bytes are counted).
    for r in rows.iter().filter(|r| r.cg_iterations_per_step.is_some()) {
        let mesh = r.mesh.rsplit('/').next().unwrap_or(&r.mesh);
        println!(
            "{mesh} {}: {:.1} CG iterations per step, {} ms per iteration, {} MB per iteration",
            r.engine,
            r.cg_iterations_per_step.unwrap_or(0.0),
            r.ms_per_cg_iteration
                .map_or("-".into(), |t| format!("{t:.4}")),
            r.bytes_per_cg_iteration
                .map_or("-".into(), |b| format!("{:.3}", b as f64 / 1e6)),
        );
    }
    for s in &report.skipped {
        println!("skipped: {s}");
    }
    Ok(ExitCode::SUCCESS)
}
