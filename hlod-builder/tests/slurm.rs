//! A sharded build on a real Slurm cluster (issue 49, item 1): the test starts
//! a single-node cluster with accounting (`scripts/slurm-local.sh`) and runs
//! `scripts/build-slurm.sh` against it. The merged scene is byte-identical to
//! one job's; a shard killed mid-run stops the merge, names the shard and exits
//! non-zero; resubmitting only that shard completes the build.
//!
//! Needs root and the packages `scripts/setup.sh` installs. Elsewhere the test
//! is skipped and listed in `target/test-skips.txt`; with `HLOD_REQUIRE_SLURM`
//! set (as `scripts/test.sh` sets it when it runs as root) it fails instead.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

use hlod_builder::build::{BuildParams, build_file};
use hlod_builder::scenegen::plant::{PlantParams, write_plant};

fn scripts() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts")
}

/// Why this machine cannot run the cluster, if it cannot.
fn unavailable() -> Option<String> {
    let root = Command::new("id")
        .arg("-u")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
        .unwrap_or(false);
    if !root {
        return Some("slurmd and munged need root".into());
    }
    for tool in [
        "/usr/sbin/slurmctld",
        "/usr/sbin/slurmd",
        "/usr/sbin/slurmdbd",
        "/usr/bin/sbatch",
        "/usr/sbin/mariadbd",
    ] {
        if !Path::new(tool).exists() {
            return Some(format!(
                "{tool} not installed (scripts/setup.sh installs it)"
            ));
        }
    }
    None
}

/// The running cluster; stopped when dropped, so a failed assertion does not
/// leave daemons behind.
struct Cluster {
    dir: PathBuf,
    conf: String,
}

impl Cluster {
    fn start(dir: &Path) -> Cluster {
        std::fs::create_dir_all(dir).unwrap();
        let out = e2e_tests::run_limited(
            Command::new("bash")
                .arg(scripts().join("slurm-local.sh"))
                .arg("start")
                .arg(dir),
            dir,
            Duration::from_secs(120),
        );
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "slurm-local.sh start failed: {}{}",
            stdout,
            String::from_utf8_lossy(&out.stderr)
        );
        let conf = stdout
            .lines()
            .find_map(|l| l.strip_prefix("export SLURM_CONF="))
            .expect("prints SLURM_CONF")
            .to_string();
        Cluster {
            dir: dir.to_path_buf(),
            conf,
        }
    }

    fn build_slurm(&self, args: &[&str], hlod_build: &Path, cwd: &Path) -> Output {
        e2e_tests::run_limited(
            Command::new("bash")
                .arg(scripts().join("build-slurm.sh"))
                .args(args)
                .env("SLURM_CONF", &self.conf)
                .env("HLOD_BUILD", hlod_build),
            cwd,
            Duration::from_secs(300),
        )
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = Command::new("bash")
            .arg(scripts().join("slurm-local.sh"))
            .arg("stop")
            .arg(&self.dir)
            .status();
    }
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

#[test]
fn shards_as_a_job_array_merge_after_all_succeed() {
    if let Some(why) = unavailable() {
        if std::env::var_os("HLOD_REQUIRE_SLURM").is_some() {
            panic!("cannot run Slurm although HLOD_REQUIRE_SLURM is set: {why}");
        }
        e2e_tests::record_skip("slurm::shards_as_a_job_array_merge_after_all_succeed", &why);
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let cluster = Cluster::start(&d.join("cluster"));
    let glb = d.join("plant.glb");
    let p = PlantParams {
        seed: 5,
        objects: 400,
        triangles: 300_000,
    };
    write_plant(&p, &glb).unwrap();
    let single = d.join("single.hlod");
    // Shards store every placement's levels: the single job does too.
    let copy = BuildParams {
        share_instances: false,
        ..BuildParams::default()
    };
    build_file(&glb, &single, &copy, false).unwrap();
    let want = std::fs::read(&single).unwrap();
    let real = PathBuf::from(env!("CARGO_BIN_EXE_hlod-build"));

    // Three shards and the merge, all through the scheduler.
    let out = cluster.build_slurm(&["--mem", "1G", "plant.glb", "3", "ok.hlod"], &real, d);
    let said = text(&out);
    assert!(out.status.success(), "{said}");
    assert_eq!(std::fs::read(d.join("ok.hlod")).unwrap(), want, "{said}");
    for job in ["shard 0 ", "shard 1 ", "shard 2 ", "merge "] {
        let line = said.lines().find(|l| l.starts_with(job));
        assert!(
            line.is_some_and(|l| l.contains("COMPLETED")),
            "no sacct line for {job}: {said}"
        );
    }

    // Shard 1's process is killed mid-run (SIGKILL, as the OOM killer or a
    // lost node would): the merge must not run.
    let killer = d.join("kill-shard-1.sh");
    std::fs::write(
        &killer,
        format!(
            "#!/bin/sh\ncase \" $* \" in *\" --shard 1/3 \"*)\n  \"{real}\" \"$@\" & pid=$!\n  kill -STOP $pid; sleep 0.2; kill -KILL $pid; wait $pid; exit $? ;;\nesac\nexec \"{real}\" \"$@\"\n",
            real = real.display()
        ),
    )
    .unwrap();
    let chmod = Command::new("chmod").arg("+x").arg(&killer).status();
    assert!(chmod.unwrap().success());
    let out = cluster.build_slurm(&["--mem", "1G", "plant.glb", "3", "re.hlod"], &killer, d);
    let said = text(&out);
    assert_eq!(out.status.code(), Some(1), "{said}");
    assert!(said.contains("shard 1 of 3 failed"), "{said}");
    assert!(!said.contains("shard 0 of 3 failed"), "{said}");
    assert!(said.contains("the merge did not run"), "{said}");
    assert!(!d.join("re.hlod").exists(), "{said}");
    let work = d.join("re.hlod.slurm");
    assert!(work.join("s-0.hlsh").exists() && work.join("s-2.hlsh").exists());
    assert!(!work.join("s-1.hlsh").exists());

    // Resubmitting only the failed shard completes the build.
    let args = ["--resume", "--mem", "1G", "plant.glb", "3", "re.hlod"];
    let out = cluster.build_slurm(&args, &real, d);
    let said = text(&out);
    assert!(out.status.success(), "{said}");
    assert!(said.contains("submitting shards 1 of 3"), "{said}");
    assert!(!said.lines().any(|l| l.starts_with("shard 0 ")), "{said}");
    assert_eq!(std::fs::read(d.join("re.hlod")).unwrap(), want, "{said}");
}
