//! The cluster route: pipelines/slurm-submit.sh's dry run, the sbatch lines it would submit.

use std::process::Command;

/// The dry run of two groups and one seed: it would build and make the templates on this
/// machine, then submit one job per run (named, singleton, with its time, CPUs, log and
/// threads, its make target) and the figures' job after all of them; it submits nothing and
/// writes nothing.
#[test]
fn slurm_submit_s_dry_run_gives_a_job_per_run_and_the_figures_after_them() {
    let root = env!("CARGO_MANIFEST_DIR");
    let out = Command::new(format!("{root}/pipelines/slurm-submit.sh"))
        .args([
            "--dry-run",
            "--time",
            "3:00:00",
            "PAPER_SEEDS=1",
            "PAPER_GROUPS=ip ab3",
            "OUT=out/dry-run-test",
            "--",
            "--partition=debug",
        ])
        .current_dir(root)
        .output()
        .expect("the script runs");
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains(
            "+ make --no-print-directory PAPER_SEEDS=1 'PAPER_GROUPS=ip ab3' OUT=out/dry-run-test build paper-templates"
        ),
        "the build before submitting: {stderr}"
    );
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), 3, "two runs and the figures: {stdout}");
    let threads = "RAYON_NUM_THREADS=$SLURM_CPUS_PER_TASK make --no-print-directory \
                   PAPER_SEEDS=1 PAPER_GROUPS=ip\\ ab3 OUT=out/dry-run-test";
    for (line, run) in lines.iter().zip(["ip-1", "ab3-1"]) {
        let expected = format!(
            "sbatch --parsable --job-name=granular-{run} --dependency=singleton --time=3:00:00 \
             --cpus-per-task=2 --output=out/dry-run-test/paper/slurm/%x-%j.out --partition=debug \
             '--wrap={threads} out/dry-run-test/paper/{run}.triax.jsonl'"
        );
        assert_eq!(*line, expected);
    }
    assert_eq!(
        lines[2],
        format!(
            "sbatch --parsable --job-name=granular-paper-figures \
             --dependency=afterok:JOB_granular-ip-1:JOB_granular-ab3-1 --time=0:30:00 \
             --cpus-per-task=2 --output=out/dry-run-test/paper/slurm/%x-%j.out \
             --partition=debug '--wrap={threads} paper'"
        )
    );
    assert!(
        !std::path::Path::new(&format!("{root}/out/dry-run-test")).exists(),
        "a dry run writes nothing"
    );
    let bad = Command::new(format!("{root}/pipelines/slurm-submit.sh"))
        .args(["--dry-run", "--cpus", "two"])
        .current_dir(root)
        .output()
        .expect("the script runs");
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--cpus must be a whole number"));
}
