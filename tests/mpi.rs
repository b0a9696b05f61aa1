//! The solve over MPI ranks (`--features mpi`; `.ci/run` installs Open MPI and builds
//! `examples/mpi_solve` first): for 1 to 4 ranks (oversubscribed on 2 cores) the flow equals
//! the single process's to 1e-10 in the same number of iterations, and a broken frame file ends
//! the whole job with the file named, without a hang.
#![cfg(feature = "mpi")]

use std::path::PathBuf;
use std::process::{Command, Output};

/// `target/<profile>/examples/mpi_solve`, beside this test's `deps` directory.
fn example() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let profile = exe.parent().and_then(|deps| deps.parent()).unwrap();
    let path = profile.join("examples").join("mpi_solve");
    assert!(
        path.exists(),
        "{} is missing: cargo build --release --features mpi --example mpi_solve",
        path.display()
    );
    path
}

/// `mpirun -n ranks mpi_solve args`, ended after 120 s should it hang (exit status 124).
fn mpirun(ranks: usize, args: &[&str]) -> Output {
    mpirun_program(ranks, &example(), args)
}

/// `mpirun -n ranks program args`, ended after 120 s should it hang (exit status 124).
fn mpirun_program(ranks: usize, program: &std::path::Path, args: &[&str]) -> Output {
    Command::new("timeout")
        .args(["120", "mpirun", "-n", &ranks.to_string()])
        .arg(program)
        .args(args)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_rmaps_base_oversubscribe", "1")
        .output()
        .expect("mpirun runs (Open MPI installed)")
}

/// The number before `what` in `text`.
fn number_before(text: &str, what: &str) -> f64 {
    let head = &text[..text
        .find(what)
        .unwrap_or_else(|| panic!("no {what:?} in {text}"))];
    head.split_whitespace().last().unwrap().parse().unwrap()
}

#[test]
fn ranks_give_the_single_process_flow() {
    for ranks in 1..=4 {
        let output = mpirun(ranks, &["--check"]);
        let stdout = String::from_utf8_lossy(&output.stdout);
        assert!(
            output.status.success(),
            "{ranks} ranks: {}",
            String::from_utf8_lossy(&output.stderr)
        );
        println!("{stdout}");
        let (distributed, single) = stdout.split_once("one process").unwrap();
        let iterations = number_before(distributed, "iterations");
        assert_eq!(
            iterations,
            number_before(single, "iterations"),
            "{ranks} ranks"
        );
        let difference: f64 = single.trim().rsplit(' ').next().unwrap().parse().unwrap();
        assert!(difference < 1e-10, "{ranks} ranks: {difference:e}");
    }
}

#[test]
fn a_broken_frame_file_ends_the_job_with_its_name() {
    let dir = tempfile::tempdir().unwrap();
    let sample = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/rotating_sphere");
    for k in 0..6 {
        let name = format!("frame_{k}.obj");
        std::fs::copy(sample.join(&name), dir.path().join(&name)).unwrap();
    }
    std::fs::write(dir.path().join("frame_4.obj"), "v 1 2\nf 1 2 3\n").unwrap();
    let output = mpirun(2, &[dir.path().to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{stderr}");
    assert_ne!(output.status.code(), Some(124), "the job hung: {stderr}");
    assert!(stderr.contains("frame_4.obj"), "{stderr}");
}

/// `mpirun -n R meshflow solve`: the outputs of one process (the flow to 1e-10 of its largest
/// value, the same files, the same iterations in the summary), for 2 and 3 ranks, and with
/// `--large-motion` (each rank warps its own slabs); with the default formats rank 0 gathers
/// the flow, without `flow.glb` the ranks stream their slabs to it (each reading only its
/// window); more ranks than slabs is a one-line error.
#[test]
fn meshflow_solve_over_ranks_writes_the_single_process_outputs() {
    let meshflow = std::path::Path::new(env!("CARGO_BIN_EXE_meshflow"));
    let sample = concat!(env!("CARGO_MANIFEST_DIR"), "/meshes/rotating_sphere");
    let dir = tempfile::tempdir().unwrap();
    let run = |ranks: usize, options: &[&str]| {
        let out = dir
            .path()
            .join(format!("ranks_{ranks}{}", options.concat()));
        let args = [
            sample,
            "--out",
            out.to_str().unwrap(),
            "--solver",
            "pcg-time-multigrid",
        ];
        let args = [&["solve"][..], &args, options].concat();
        let output = mpirun_program(ranks, meshflow, &args);
        let stderr = String::from_utf8_lossy(&output.stderr).to_string();
        (output.status.success(), out, stderr)
    };
    let read = |out: &std::path::Path| {
        let array = meshflow::io::read_npy_float(&out.join("flow_intrinsic.npy")).unwrap();
        let summary = std::fs::read_to_string(out.join("summary.json")).unwrap();
        let summary: serde_json::Value = serde_json::from_str(&summary).unwrap();
        let keys = [
            "iterations",
            "frames",
            "slabs",
            "times",
            "warnings",
            "welded_vertices",
        ];
        let facts: Vec<_> = keys.iter().map(|k| summary[k].clone()).collect();
        (array.data, array.shape, facts)
    };
    let names = |d: &std::path::Path| {
        let mut n: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        n.sort();
        n
    };
    let streamed = ["--format", "npy,vtu"];
    let streamed_warping = ["--format", "npy,vtu", "--large-motion"];
    for (options, rank_counts) in [
        (&[][..], &[2, 3][..]),
        (&["--large-motion"][..], &[2][..]),
        (&streamed[..], &[2, 3][..]),
        (&streamed_warping[..], &[3][..]),
    ] {
        let (ok, single, stderr) = run(1, options);
        assert!(ok, "{stderr}");
        let (expected, shape, iterations) = read(&single);
        let scale = expected.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for &ranks in rank_counts {
            let (ok, out, stderr) = run(ranks, options);
            assert!(ok, "{ranks} ranks {options:?}: {stderr}");
            let (values, got_shape, got_iterations) = read(&out);
            assert_eq!(got_shape, shape);
            assert_eq!(got_iterations, iterations, "{ranks} ranks {options:?}");
            let difference =
                (values.iter().zip(&expected)).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            println!(
                "{ranks} ranks {options:?}: flow differs by {:.1e} of its largest value",
                difference / scale
            );
            assert!(difference < 1e-10 * scale, "{ranks} ranks: {difference:e}");
            assert_eq!(names(&out), names(&single), "{ranks} ranks {options:?}");
        }
    }
    let (ok, _, stderr) = run(6, &[]);
    assert!(!ok);
    assert!(stderr.contains("6 ranks for 5 slabs"), "{stderr}");
}
