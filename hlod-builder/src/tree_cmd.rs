//! `hlod-build info --tree`: a scene's model tree (site, building, storey,
//! type; or the glTF node hierarchy) as the viewer's panel shows it, with
//! what making it costs: its time and the heap it holds.

use anyhow::{Context, Result};
use engine::tree::ModelTree;
use engine::{ByteSource, SceneFile};

/// Groups printed under one group at most.
const MAX_SHOWN: usize = 40;

/// Prints `scene`'s model tree down to `depth` levels of groups.
pub fn print_tree<S: ByteSource>(scene: &SceneFile<S>, name: &str, depth: usize) -> Result<()> {
    let table = scene.read_objects().context("the object section")?;
    let before = hlod_builder::heap::in_use();
    let t = std::time::Instant::now();
    let drawn = engine::tree::drawn_objects(scene.skeleton(), &table);
    let tree = ModelTree::new(&table, name, &drawn);
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let held = hlod_builder::heap::in_use()
        .zip(before)
        .map(|(a, b)| a.saturating_sub(b));
    tree.validate()
        .map_err(|e| anyhow::anyhow!("model tree: {e}"))?;
    println!(
        "model tree: {} groups over {} elements, made in {ms:.1} ms{}",
        tree.groups().len(),
        table.len(),
        held.map_or(String::new(), |b| format!(
            ", {:.2} MiB held",
            b as f64 / 1048576.0
        ))
    );
    let mut stack = vec![(0u32, 0usize)];
    while let Some((g, d)) = stack.pop() {
        let grp = &tree.groups()[g as usize];
        println!(
            "{}{} ({:?}, {} elements)",
            "  ".repeat(d + 1),
            grp.label,
            grp.level,
            tree.objects(g).len()
        );
        if d + 1 > depth {
            continue;
        }
        if grp.children.len() > MAX_SHOWN {
            println!(
                "{}… {} groups in all, the first {MAX_SHOWN} shown",
                "  ".repeat(d + 2),
                grp.children.len()
            );
        }
        for &c in grp.children.iter().take(MAX_SHOWN).rev() {
            stack.push((c, d + 1));
        }
    }
    Ok(())
}
