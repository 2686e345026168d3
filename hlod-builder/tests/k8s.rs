//! The Kubernetes manifests of a sharded build (`hlod-builder/deploy/k8s/`,
//! issue 49, item 2). No `kubectl` or cluster runs here, so the manifests are
//! checked in two ways instead:
//! - **against the Job schema**, for the fields they use: each file is read
//!   into typed structs that mirror the Kubernetes API objects (`batch/v1`
//!   Job, JobSpec, PodSpec, Container, ...) with unknown fields refused, so a
//!   misspelt or misplaced field, a wrong type, an invalid name, quantity or
//!   enum value fails; plus the API server's rules that apply to these fields
//!   (Indexed needs `completions`; `backoffLimitPerIndex` needs Indexed and
//!   `restartPolicy: Never`; volume mounts name a volume);
//! - **by running their commands**: the shard Job's `args` for every index and
//!   the merge Job's `args`, with `$(JOB_COMPLETION_INDEX)` expanded as
//!   Kubernetes does and `/data` mapped to a temporary folder, run through the
//!   real `hlod-build` and give the single job's bytes.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use hlod_builder::build::{BuildParams, build_file};
use hlod_builder::scenegen::plant::{PlantParams, write_plant};
use serde::Deserialize;

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, rename_all = "camelCase")]
struct Job {
    api_version: String,
    kind: String,
    metadata: ObjectMeta,
    spec: JobSpec,
}

#[derive(Deserialize, Debug, Default)]
#[serde(deny_unknown_fields, rename_all = "camelCase")]
struct ObjectMeta {
    name: Option<String>,
    #[serde(default)]
    labels: BTreeMap<String, String>,
    #[serde(default)]
    annotations: BTreeMap<String, String>,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, rename_all = "camelCase")]
struct JobSpec {
    completions: Option<i32>,
    parallelism: Option<i32>,
    completion_mode: Option<String>,
    backoff_limit: Option<i32>,
    backoff_limit_per_index: Option<i32>,
    max_failed_indexes: Option<i32>,
    active_deadline_seconds: Option<i64>,
    ttl_seconds_after_finished: Option<i32>,
    template: PodTemplateSpec,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, rename_all = "camelCase")]
struct PodTemplateSpec {
    #[serde(default)]
    metadata: ObjectMeta,
    spec: PodSpec,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, rename_all = "camelCase")]
struct PodSpec {
    restart_policy: Option<String>,
    containers: Vec<Container>,
    #[serde(default)]
    volumes: Vec<Volume>,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, rename_all = "camelCase")]
struct Container {
    name: String,
    image: String,
    #[serde(default)]
    command: Vec<String>,
    #[serde(default)]
    args: Vec<String>,
    #[serde(default)]
    env: Vec<EnvVar>,
    resources: Option<Resources>,
    #[serde(default)]
    volume_mounts: Vec<VolumeMount>,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct EnvVar {
    name: String,
    value: String,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
struct Resources {
    #[serde(default)]
    requests: BTreeMap<String, String>,
    #[serde(default)]
    limits: BTreeMap<String, String>,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, rename_all = "camelCase")]
struct VolumeMount {
    name: String,
    mount_path: String,
    read_only: Option<bool>,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, rename_all = "camelCase")]
struct Volume {
    name: String,
    persistent_volume_claim: Pvc,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, rename_all = "camelCase")]
struct Pvc {
    claim_name: String,
    read_only: Option<bool>,
}

fn deploy() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/deploy"))
}

/// Reads one manifest into the schema types; the error names the field.
fn read_job(name: &str) -> Result<Job, String> {
    let text =
        std::fs::read_to_string(deploy().join("k8s").join(name)).map_err(|e| e.to_string())?;
    parse_job(&text).map_err(|e| format!("{name}: {e}"))
}

fn parse_job(text: &str) -> Result<Job, String> {
    let de = serde_norway::Deserializer::from_str(text);
    let job: Job = serde_path_to_error::deserialize(de).map_err(|e| e.to_string())?;
    check_job(&job)?;
    Ok(job)
}

/// RFC 1123 label: what Kubernetes requires of container, volume and (at
/// most 63 characters, as a Job's pods carry it in a label) Job names.
fn dns_label(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 63
        && s.bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-')
        && !s.starts_with('-')
        && !s.ends_with('-')
}

/// A resource quantity as the API accepts it: a number with an optional
/// binary (Ki..Ei), decimal (k..E) or milli suffix.
fn quantity(s: &str) -> bool {
    let digits = s.trim_end_matches(|c: char| c.is_ascii_alphabetic());
    let suffix = &s[digits.len()..];
    !digits.is_empty()
        && digits.parse::<f64>().is_ok_and(|v| v >= 0.0)
        && [
            "", "m", "k", "M", "G", "T", "P", "E", "Ki", "Mi", "Gi", "Ti", "Pi", "Ei",
        ]
        .contains(&suffix)
}

/// Label and annotation keys (an optional DNS prefix and `/`, then a name of
/// at most 63 characters) and label values (at most 63 characters).
fn check_meta(m: &ObjectMeta, at: &str) -> Result<(), String> {
    let name_ok = |n: &str| {
        !n.is_empty()
            && n.len() <= 63
            && n.bytes()
                .all(|b| b.is_ascii_alphanumeric() || b"-_.".contains(&b))
    };
    for k in m.labels.keys().chain(m.annotations.keys()) {
        let name = k.rsplit_once('/').map_or(k.as_str(), |(_, n)| n);
        if !name_ok(name) {
            return Err(format!("{at}: label or annotation key {k:?}"));
        }
    }
    match m.labels.values().find(|v| !v.is_empty() && !name_ok(v)) {
        Some(v) => Err(format!("{at}: label value {v:?}")),
        None => Ok(()),
    }
}

fn check_job(job: &Job) -> Result<(), String> {
    check_meta(&job.metadata, "metadata")?;
    check_meta(&job.spec.template.metadata, "template.metadata")?;
    let fail = |what: String| Err(what);
    if job.api_version != "batch/v1" || job.kind != "Job" {
        return fail(format!(
            "apiVersion/kind {}/{}, want batch/v1 Job",
            job.api_version, job.kind
        ));
    }
    let name = job.metadata.name.as_deref().unwrap_or("");
    if !dns_label(name) {
        return fail(format!("metadata.name {name:?} is not a DNS-1123 label"));
    }
    let s = &job.spec;
    for (field, v) in [
        ("completions", s.completions),
        ("parallelism", s.parallelism),
        ("backoffLimit", s.backoff_limit),
        ("backoffLimitPerIndex", s.backoff_limit_per_index),
        ("maxFailedIndexes", s.max_failed_indexes),
        ("ttlSecondsAfterFinished", s.ttl_seconds_after_finished),
    ] {
        if v.is_some_and(|v| v < 0) {
            return fail(format!("spec.{field} is negative"));
        }
    }
    if s.active_deadline_seconds.is_some_and(|v| v <= 0) {
        return fail("spec.activeDeadlineSeconds must be positive".into());
    }
    let indexed = match s.completion_mode.as_deref() {
        None | Some("NonIndexed") => false,
        Some("Indexed") => true,
        Some(m) => return fail(format!("spec.completionMode {m:?}: NonIndexed or Indexed")),
    };
    if indexed && s.completions.is_none() {
        return fail("spec.completions is required with completionMode Indexed".into());
    }
    let pod = &s.template.spec;
    let restart = pod.restart_policy.as_deref();
    if !matches!(restart, Some("Never" | "OnFailure")) {
        return fail(format!(
            "template.spec.restartPolicy {restart:?}: a Job needs Never or OnFailure"
        ));
    }
    if s.backoff_limit_per_index.is_some() && (!indexed || restart != Some("Never")) {
        return fail(
            "spec.backoffLimitPerIndex needs completionMode Indexed and restartPolicy Never".into(),
        );
    }
    if s.max_failed_indexes.is_some() && s.backoff_limit_per_index.is_none() {
        return fail("spec.maxFailedIndexes needs backoffLimitPerIndex".into());
    }
    if pod.containers.is_empty() {
        return fail("template.spec.containers is empty".into());
    }
    for v in &pod.volumes {
        if !dns_label(&v.name) || !dns_label(&v.persistent_volume_claim.claim_name) {
            return fail(format!(
                "volume {:?} or its claim is not a DNS-1123 label",
                v.name
            ));
        }
    }
    for c in &pod.containers {
        if !dns_label(&c.name) || c.image.is_empty() {
            return fail(format!("container {:?}: name or image", c.name));
        }
        if let Some(r) = &c.resources {
            for (k, v) in r.requests.iter().chain(&r.limits) {
                if !["cpu", "memory", "ephemeral-storage"].contains(&k.as_str()) || !quantity(v) {
                    return fail(format!("container {}: resource {k}: {v:?}", c.name));
                }
            }
        }
        for m in &c.volume_mounts {
            if !pod.volumes.iter().any(|v| v.name == m.name) || !m.mount_path.starts_with('/') {
                return fail(format!(
                    "container {}: mount {:?} names no volume",
                    c.name, m.name
                ));
            }
        }
    }
    Ok(())
}

/// The container's arguments with `$(NAME)` references expanded from `env`,
/// as the kubelet expands them.
fn expand(args: &[String], env: &BTreeMap<&str, String>) -> Vec<String> {
    args.iter()
        .map(|a| {
            let mut a = a.clone();
            for (k, v) in env {
                a = a.replace(&format!("$({k})"), v);
            }
            assert!(!a.contains("$("), "unexpanded reference in {a}");
            a
        })
        .collect()
}

#[test]
fn the_schema_check_catches_mistakes() {
    let good = std::fs::read_to_string(deploy().join("k8s/shards-job.yaml")).unwrap();
    assert!(parse_job(&good).is_ok());
    for (from, to, needle) in [
        (
            "completionMode: Indexed",
            "completionMode: indexed",
            "completionMode",
        ),
        (
            "backoffLimitPerIndex:",
            "backofLimitPerIndex:",
            "backofLimitPerIndex",
        ),
        (
            "restartPolicy: Never",
            "restartPolicy: Always",
            "restartPolicy",
        ),
        ("completions: 16", "completions: many", "completions"),
        ("memory: 8Gi", "memory: 8 GB", "memory"),
        ("name: hlod-shards", "name: HLOD_shards", "metadata.name"),
        ("claimName: hlod-data", "claimNme: hlod-data", "claimNme"),
        ("mountPath: /data", "mountPath: data", "mount"),
    ] {
        assert!(good.contains(from), "{from}");
        let bad = good.replacen(from, to, 1);
        let err = parse_job(&bad).expect_err(to);
        assert!(err.contains(needle), "{to}: {err}");
    }
}

#[test]
fn manifests_are_jobs_whose_commands_build_the_scene() {
    let shards = read_job("shards-job.yaml").unwrap();
    let merge = read_job("merge-job.yaml").unwrap();
    let n = shards.spec.completions.unwrap();
    assert_eq!(shards.spec.completion_mode.as_deref(), Some("Indexed"));
    assert_eq!(merge.spec.completions, Some(1));
    let (sc, mc) = (
        &shards.spec.template.spec.containers[0],
        &merge.spec.template.spec.containers[0],
    );
    assert_eq!(sc.image, mc.image, "both Jobs run the same image");
    let claim = |j: &Job| {
        j.spec.template.spec.volumes[0]
            .persistent_volume_claim
            .claim_name
            .clone()
    };
    assert_eq!(
        claim(&shards),
        claim(&merge),
        "both Jobs mount the same data"
    );
    for j in [&shards, &merge] {
        let pod = &j.spec.template.spec;
        assert!(
            pod.volumes
                .iter()
                .all(|v| v.persistent_volume_claim.read_only != Some(true))
        );
        let mounts = &pod.containers[0].volume_mounts;
        assert!(
            mounts.iter().all(|m| m.read_only != Some(true)),
            "the Jobs write to /data"
        );
    }
    // The image's entrypoint is hlod-build (no `command` override).
    assert!(sc.command.is_empty() && mc.command.is_empty());
    let dockerfile = std::fs::read_to_string(deploy().join("Dockerfile")).unwrap();
    assert!(dockerfile.contains("ENTRYPOINT [\"/usr/local/bin/hlod-build\"]"));

    // Run every command as the Jobs would, on a small plant under /data.
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path();
    std::fs::create_dir_all(data.join("shards")).unwrap();
    let p = PlantParams {
        seed: 9,
        objects: 120,
        triangles: 40_000,
    };
    write_plant(&p, &data.join("MODEL.glb")).unwrap();
    let single = data.join("single.hlod");
    // Shards store every placement's levels: the single job does too.
    build_file(
        &data.join("MODEL.glb"),
        &single,
        &BuildParams {
            share_instances: false,
            ..BuildParams::default()
        },
        false,
    )
    .unwrap();
    let map = |a: Vec<String>| -> Vec<String> {
        a.into_iter()
            .map(|s| s.replace("/data/", &format!("{}/", data.display())))
            .collect()
    };
    let run = |args: Vec<String>, env: &[EnvVar]| {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_hlod-build"));
        cmd.args(map(args));
        for e in env {
            cmd.env(&e.name, &e.value);
        }
        let out = cmd.output().unwrap();
        assert!(
            out.status.success(),
            "{cmd:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    for i in 0..n {
        let mut env: BTreeMap<&str, String> = sc
            .env
            .iter()
            .map(|e| (e.name.as_str(), e.value.clone()))
            .collect();
        env.insert("JOB_COMPLETION_INDEX", i.to_string());
        run(expand(&sc.args, &env), &sc.env);
    }
    // The merge names exactly the files the shards wrote.
    let written: Vec<String> = (0..n).map(|i| format!("/data/shards/s-{i}.hlsh")).collect();
    let named: Vec<String> = mc
        .args
        .iter()
        .filter(|a| a.ends_with(".hlsh"))
        .cloned()
        .collect();
    assert_eq!(named, written);
    run(expand(&mc.args, &BTreeMap::new()), &mc.env);
    let merged = std::fs::read(data.join("MODEL.hlod")).unwrap();
    assert_eq!(
        merged,
        std::fs::read(&single).unwrap(),
        "the Jobs' scene equals one job's"
    );
}
