//! `hlod-build publish SCENE s3://BUCKET/KEY`: uploads a scene file to
//! S3-compatible object storage, where viewers can stream it from.
//!
//! The upload is one S3 multipart upload straight to the final key. S3 makes
//! such an object visible only when the upload is completed, so the key shows
//! either what it held before or the whole new file, never a part of it. Every
//! part is checked before completing: the ETag S3 returns for a part is the MD5
//! of the bytes it stored, compared with the MD5 of the bytes sent. Any error or
//! mismatch aborts the upload (nothing is written under the key; the parts are
//! deleted). After completing, the object's size and its multipart ETag (the
//! MD5 of the parts' MD5s) are checked once more. Writing to a temporary key and
//! copying it (S3 has no rename) would write every byte twice, and S3's single
//! copy stops at 5 GiB.
//!
//! Credentials and the endpoint come from the usual environment variables
//! (`AWS_ACCESS_KEY_ID`, `AWS_SECRET_ACCESS_KEY`, `AWS_SESSION_TOKEN`,
//! `AWS_REGION` / `AWS_DEFAULT_REGION`, `AWS_ENDPOINT_URL`, `AWS_ALLOW_HTTP`
//! for a plain-HTTP endpoint), read by `object_store`; never from the command
//! line, and never printed.

use std::io::{Read, Seek, SeekFrom};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use md5::{Digest, Md5};
use object_store::aws::{AmazonS3, AmazonS3Builder};
use object_store::multipart::{MultipartStore, PartId};
use object_store::path::Path as ObjectPath;
use object_store::{ObjectStoreExt, PutPayload, RetryConfig};

/// S3's limits on multipart uploads.
const MIN_PART: u64 = 5 << 20;
const MAX_PART: u64 = 5 << 30;
const MAX_PARTS: u64 = 10_000;

#[derive(clap::Args, Debug)]
pub struct PublishArgs {
    /// The scene file (checked before anything is sent).
    scene: PathBuf,
    /// Where to: s3://BUCKET/KEY.
    url: String,
    /// Bytes per part, e.g. 64M (5M to 5G; raised when the file would need
    /// more than 10,000 parts).
    #[arg(long, default_value = "64M", value_parser = hlod_builder::build::memory::parse_size)]
    part_size: u64,
    /// Parts uploaded at once (each holds one part in memory).
    #[arg(long, default_value_t = 4)]
    parallel: usize,
    /// Retries of a failed request, with backoff, before the upload is
    /// aborted.
    #[arg(long, default_value_t = 5)]
    retries: usize,
}

/// `s3://bucket/key` → (bucket, key).
fn parse_url(url: &str) -> Result<(String, String)> {
    let Some(rest) = url.strip_prefix("s3://") else {
        bail!("{url:?}: publish writes to s3://BUCKET/KEY");
    };
    match rest.split_once('/') {
        Some((bucket, key)) if !bucket.is_empty() && !key.is_empty() && !key.ends_with('/') => {
            Ok((bucket.to_string(), key.to_string()))
        }
        _ => bail!("{url:?}: want s3://BUCKET/KEY with a bucket and an object key"),
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// An ETag without its quotes, lower case.
fn bare(etag: &str) -> String {
    etag.trim().trim_matches('"').to_ascii_lowercase()
}

pub fn publish(a: &PublishArgs) -> Result<()> {
    let (bucket, key) = parse_url(&a.url)?;
    if a.parallel == 0 {
        bail!("--parallel must be at least 1");
    }
    if !(MIN_PART..=MAX_PART).contains(&a.part_size) {
        bail!("--part-size must be between 5M and 5G (S3's limits on a part)");
    }
    // Only a valid scene goes out (header, skeleton, trailer).
    let scene =
        engine::SceneFile::open(&a.scene).with_context(|| format!("{}", a.scene.display()))?;
    drop(scene);
    let len = std::fs::metadata(&a.scene)
        .with_context(|| format!("{}", a.scene.display()))?
        .len();
    let part = a
        .part_size
        .max(len.div_ceil(MAX_PARTS).next_multiple_of(1 << 20));
    let parts = len.div_ceil(part).max(1);

    let store = AmazonS3Builder::from_env()
        .with_bucket_name(&bucket)
        .with_retry(RetryConfig {
            max_retries: a.retries,
            retry_timeout: Duration::from_secs(120),
            ..RetryConfig::default()
        })
        .build()
        .with_context(|| format!("{}: the S3 settings from the environment", a.url))?;
    let store = Arc::new(store);
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(a.parallel.min(8))
        .enable_all()
        .build()
        .context("starting the upload's runtime")?;
    let path = ObjectPath::from(key.as_str());
    let t = Instant::now();
    let id = rt
        .block_on(store.create_multipart(&path))
        .with_context(|| format!("{}: starting the upload", a.url))?;
    let sent = rt.block_on(upload_parts(&store, &path, &id, a, part, parts));
    let md5s = match sent {
        Ok(md5s) => md5s,
        Err(e) => {
            let aborted = rt.block_on(store.abort_multipart(&path, &id));
            let left = match aborted {
                Ok(()) => "nothing was written under it".to_string(),
                Err(_) => format!(
                    "nothing was written under it, but aborting upload {id} failed: its parts \
                     stay until a lifecycle rule removes them"
                ),
            };
            return Err(e.context(format!("{}: upload failed; {left}", a.url)));
        }
    };
    let ids: Vec<PartId> = md5s.iter().map(|(_, id)| id.clone()).collect();
    if let Err(e) = rt.block_on(store.complete_multipart(&path, &id, ids)) {
        let _ = rt.block_on(store.abort_multipart(&path, &id));
        return Err(anyhow::Error::new(e).context(format!(
            "{}: completing the upload failed; nothing was written under it",
            a.url
        )));
    }
    // The object as stored now: its size and its multipart ETag.
    let meta = rt
        .block_on(store.head(&path))
        .with_context(|| format!("{}: reading back the object's size and ETag", a.url))?;
    let mut all = Md5::new();
    for (m, _) in &md5s {
        all.update(m);
    }
    let want = format!("{}-{}", hex(&all.finalize()), md5s.len());
    let got = meta.e_tag.as_deref().map(bare).unwrap_or_default();
    if meta.size != len || got != want {
        bail!(
            "{}: the stored object is not the file sent (size {} against {len}, ETag {got:?} \
             against {want:?}): another writer may have replaced it",
            a.url,
            meta.size
        );
    }
    let secs = t.elapsed().as_secs_f64();
    println!(
        "published {} to {} ({:.1} MiB in {parts} part(s) of {} MiB, each checked by MD5; ETag {want}) in {secs:.1} s, {:.1} MiB/s",
        a.scene.display(),
        a.url,
        len as f64 / 1048576.0,
        part >> 20,
        len as f64 / 1048576.0 / secs.max(1e-9),
    );
    Ok(())
}

/// Uploads every part, `a.parallel` at once, and checks each part's ETag
/// against the MD5 of what was sent. Returns the parts' MD5s and ids in order.
async fn upload_parts(
    store: &Arc<AmazonS3>,
    path: &ObjectPath,
    id: &str,
    a: &PublishArgs,
    part: u64,
    parts: u64,
) -> Result<Vec<([u8; 16], PartId)>> {
    let mut file =
        std::fs::File::open(&a.scene).with_context(|| format!("{}", a.scene.display()))?;
    let mut done: Vec<Option<([u8; 16], PartId)>> = vec![None; parts as usize];
    let mut running = tokio::task::JoinSet::new();
    for i in 0..parts {
        if running.len() >= a.parallel {
            let (j, m, pid) = running.join_next().await.expect("a task runs")??;
            done[j as usize] = Some((m, pid));
        }
        let mut buf = Vec::new();
        file.seek(SeekFrom::Start(i * part))
            .and_then(|_| (&mut file).take(part).read_to_end(&mut buf))
            .with_context(|| format!("{}: reading part {}", a.scene.display(), i + 1))?;
        let md5: [u8; 16] = Md5::digest(&buf).into();
        let (store, path, id) = (Arc::clone(store), path.clone(), id.to_string());
        running.spawn(async move {
            let pid = store
                .put_part(&path, &id, i as usize, PutPayload::from(buf))
                .await
                .with_context(|| format!("part {} of {parts}", i + 1))?;
            if bare(&pid.content_id) != hex(&md5) {
                bail!(
                    "part {} of {parts}: the server stored other bytes than were sent (its MD5 {}, ours {})",
                    i + 1,
                    bare(&pid.content_id),
                    hex(&md5)
                );
            }
            Ok::<_, anyhow::Error>((i, md5, pid))
        });
    }
    while let Some(r) = running.join_next().await {
        let (j, m, pid) = r??;
        done[j as usize] = Some((m, pid));
    }
    Ok(done
        .into_iter()
        .map(|d| d.expect("every part sent"))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls() {
        assert_eq!(
            parse_url("s3://b/scenes/plant.hlod").unwrap(),
            ("b".into(), "scenes/plant.hlod".into())
        );
        for bad in ["http://b/k", "s3://b", "s3://b/", "s3:///k", "s3://b/dir/"] {
            assert!(parse_url(bad).is_err(), "{bad}");
        }
        assert_eq!(bare("\"ABC\""), "abc");
    }
}
