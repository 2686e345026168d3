//! The model tree: the scene's elements grouped as a BIM user looks for
//! them (site, building, storey, IFC type, element), built from the object
//! section alone, never from geometry. Where the file carries no IFC
//! spatial structure (a glTF export, a CAD assembly), the glTF node
//! hierarchy gives the groups, then the IFC type where the names carry
//! one.
//!
//! Every group holds a contiguous range of [`ModelTree::order`], so what
//! the panel does to a group (hide, isolate, x-ray) is a slice of objects:
//! [`ModelTree::apply`] rewrites the objects' [`Look`]s, and
//! [`crate::hide::Hiding::with_looks`] turns them into what P_R draws and
//! P_I fetches.

use std::cmp::Ordering;
use std::ops::Range;

use serde_json::Value;

use crate::format::NONE;
use crate::format::objects::ObjectTable;

/// How one object is drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(u8)]
pub enum Look {
    #[default]
    Shown = 0,
    /// Not drawn, not fetched.
    Hidden = 1,
    /// Drawn translucent over the rest, hiding nothing (not an occluder,
    /// not picked).
    XRay = 2,
}

/// What an object's description says of it: the fields of its JSON text in
/// the object section that a user sorts and searches by.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Described {
    /// The glTF node's name.
    pub name: String,
    pub mesh_name: String,
    /// IFC class (`extras` `type` and its spellings, else an IFC-style
    /// name `IfcClass:Name:GlobalId`).
    pub ifc_type: String,
    pub global_id: String,
    /// The IFC `Name` (`extras`), else the middle of an IFC-style name.
    pub ifc_name: String,
    pub site: String,
    pub building: String,
    pub storey: String,
    pub storey_elevation: Option<f64>,
    /// The glTF nodes above the object's node, outermost first.
    pub parents: Vec<String>,
    /// World box (`box_min`, `box_max`), when the description has it.
    pub bounds: Option<([f64; 3], [f64; 3])>,
}

impl Described {
    /// Reads an object's description; what it lacks stays empty (text that
    /// is not JSON describes nothing).
    pub fn parse(info: &str) -> Self {
        Self::of(&serde_json::from_str(info).unwrap_or(Value::Null))
    }

    /// What the description `v`, already parsed, says.
    pub fn of(v: &Value) -> Self {
        let text = |x: Option<&Value>| match x {
            Some(Value::String(s)) => s.clone(),
            Some(Value::Number(n)) => n.to_string(),
            _ => String::new(),
        };
        let extra = |keys: &[&str]| -> Option<&Value> {
            ["extras", "mesh_extras"]
                .iter()
                .filter_map(|s| v.get(s)?.as_object())
                .flat_map(|m| m.iter())
                .find(|(k, val)| {
                    keys.contains(&k.to_ascii_lowercase().as_str()) && !text(Some(val)).is_empty()
                })
                .map(|(_, val)| val)
        };
        let find = |keys: &[&str]| text(extra(keys));
        let name = text(v.get("name"));
        let mut ifc_type = find(&[
            "type", "ifctype", "ifc_type", "ifcclass", "class", "category",
        ]);
        let mut global_id = find(&["globalid", "global_id", "guid", "ifcguid", "ifc_guid"]);
        let mut ifc_name = find(&["name"]);
        let parts: Vec<&str> = name.split(':').collect();
        if parts.len() >= 3 && parts[0].starts_with("Ifc") {
            if ifc_type.is_empty() {
                ifc_type = parts[0].to_string();
            }
            if global_id.is_empty() && parts[parts.len() - 1].len() == 22 {
                global_id = parts[parts.len() - 1].to_string();
            }
            if ifc_name.is_empty() {
                ifc_name = parts[1..parts.len() - 1].join(":");
            }
        }
        let triple = |k: &str| -> Option<[f64; 3]> {
            let a = v.get(k)?.as_array()?;
            Some([
                a.first()?.as_f64()?,
                a.get(1)?.as_f64()?,
                a.get(2)?.as_f64()?,
            ])
        };
        Self {
            mesh_name: text(v.get("mesh_name")),
            ifc_type,
            global_id,
            ifc_name,
            site: find(&["site"]),
            building: find(&["building"]),
            storey: find(&["storey", "level", "buildingstorey"]),
            storey_elevation: extra(&["storey_elevation"]).and_then(Value::as_f64),
            parents: match v.get("parents") {
                Some(Value::Array(a)) => a.iter().map(|p| text(Some(p))).collect(),
                _ => Vec::new(),
            },
            bounds: triple("box_min").zip(triple("box_max")),
            name,
        }
    }

    /// What the tree shows for it: the IFC name, else the node's name.
    pub fn label(&self) -> &str {
        if self.ifc_name.is_empty() {
            &self.name
        } else {
            &self.ifc_name
        }
    }
}

/// What a group of the tree stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Level {
    Model,
    Site,
    Building,
    Storey,
    /// A glTF node that groups others (no IFC structure in the file).
    Group,
    /// An IFC class.
    Type,
    /// The elements the build left out (IFC openings' voids and spaces):
    /// described, never drawn.
    LeftOut,
}

/// One group of the tree.
#[derive(Clone, Debug, PartialEq)]
pub struct Group {
    pub label: String,
    pub level: Level,
    /// `None` for the model (the root, group 0).
    pub parent: Option<u32>,
    /// Its groups, in the tree's order.
    pub children: Vec<u32>,
    /// Its objects, in [`ModelTree::order`] (those of its groups included).
    pub objects: Range<u32>,
    /// The objects directly in it (in no group of its own), a tail of
    /// `objects`.
    pub direct: Range<u32>,
}

/// How many objects of a group are drawn which way.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    pub shown: u32,
    pub hidden: u32,
    pub xray: u32,
}

/// What the panel does to a group's (or an element's) objects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Op {
    Hide,
    Show,
    /// Shows these, hides every other object.
    Isolate,
    XRay,
    /// Shows these, x-rays every other object not hidden (the model as
    /// context around them).
    XRayOthers,
}

/// The scene's elements in groups.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ModelTree {
    groups: Vec<Group>,
    /// Every object once, each group's a contiguous range.
    order: Vec<u32>,
    /// Per object: its label, GlobalId, world box and innermost group.
    labels: Vec<Box<str>>,
    ids: Vec<Box<str>>,
    bounds: Vec<Option<([f64; 3], [f64; 3])>>,
    group_of: Vec<u32>,
}

/// One step of an object's path from the root: its level, a sort key and
/// the label.
#[derive(Clone, Debug, PartialEq)]
struct Step {
    level: Level,
    key: f64,
    label: String,
}

fn cmp_steps(a: &[Step], b: &[Step]) -> Ordering {
    for (x, y) in a.iter().zip(b) {
        let o = (x.level.cmp(&y.level))
            .then(x.key.total_cmp(&y.key))
            .then_with(|| x.label.cmp(&y.label));
        if o != Ordering::Equal {
            return o;
        }
    }
    // Objects directly in a group come after its subgroups.
    b.len().cmp(&a.len())
}

impl ModelTree {
    /// The tree of `table`'s objects, its root labelled `model`; the
    /// objects `drawn` marks false (an empty list marks none) go to one
    /// last group of what the build left out.
    pub fn new(table: &ObjectTable, model: &str, drawn: &[bool]) -> Self {
        let n = table.len();
        let described: Vec<Described> = (0..n as u32)
            .map(|k| Described::parse(table.info(k).unwrap_or("")))
            .collect();
        let mut paths = paths(&described);
        for (p, _) in paths.iter_mut().zip(drawn).filter(|(_, d)| !**d) {
            *p = vec![Step {
                level: Level::LeftOut,
                key: 0.0,
                label: "left out by the build (not drawn)".into(),
            }];
        }
        let mut order: Vec<u32> = (0..n as u32).collect();
        order.sort_by(|&a, &b| {
            let (da, db) = (&described[a as usize], &described[b as usize]);
            cmp_steps(&paths[a as usize], &paths[b as usize])
                .then_with(|| da.label().cmp(db.label()))
                .then(a.cmp(&b))
        });
        let mut tree = Self {
            groups: vec![Group {
                label: model.to_string(),
                level: Level::Model,
                parent: None,
                children: Vec::new(),
                objects: 0..n as u32,
                direct: 0..0,
            }],
            labels: described.iter().map(|d| d.label().into()).collect(),
            ids: described
                .iter()
                .map(|d| d.global_id.as_str().into())
                .collect(),
            bounds: described.iter().map(|d| d.bounds).collect(),
            group_of: vec![0; n],
            order,
        };
        tree.split(0, 0, &paths);
        tree
    }

    /// Splits group `g` (objects at path depth `depth`) into subgroups by
    /// their step at `depth`; what has no step there is direct.
    fn split(&mut self, g: u32, depth: usize, paths: &[Vec<Step>]) {
        let range = self.groups[g as usize].objects.clone();
        let mut i = range.start;
        while i < range.end {
            let path = &paths[self.order[i as usize] as usize];
            let Some(step) = path.get(depth) else {
                // Sorted after every subgroup: the rest is direct.
                self.groups[g as usize].direct = i..range.end;
                for &k in &self.order[i as usize..range.end as usize] {
                    self.group_of[k as usize] = g;
                }
                break;
            };
            let mut j = i + 1;
            while j < range.end
                && paths[self.order[j as usize] as usize]
                    .get(depth)
                    .is_some_and(|s| s == step)
            {
                j += 1;
            }
            let child = self.groups.len() as u32;
            self.groups.push(Group {
                label: step.label.clone(),
                level: step.level,
                parent: Some(g),
                children: Vec::new(),
                objects: i..j,
                direct: j..j,
            });
            self.groups[g as usize].children.push(child);
            self.split(child, depth + 1, paths);
            i = j;
        }
        let g = &mut self.groups[g as usize];
        if g.direct.is_empty() {
            g.direct = range.end..range.end;
        }
    }

    /// The groups; 0 is the model.
    pub fn groups(&self) -> &[Group] {
        &self.groups
    }

    /// Group `g`'s objects (its subgroups' included).
    pub fn objects(&self, g: u32) -> &[u32] {
        let r = &self.groups[g as usize].objects;
        &self.order[r.start as usize..r.end as usize]
    }

    /// The objects directly in group `g`.
    pub fn direct(&self, g: u32) -> &[u32] {
        let r = &self.groups[g as usize].direct;
        &self.order[r.start as usize..r.end as usize]
    }

    /// Object `k`'s label in the tree.
    pub fn label(&self, k: u32) -> &str {
        self.labels.get(k as usize).map_or("", |s| s)
    }

    /// Object `k`'s GlobalId (empty if it has none).
    pub fn global_id(&self, k: u32) -> &str {
        self.ids.get(k as usize).map_or("", |s| s)
    }

    /// The group object `k` is directly in.
    pub fn group_of(&self, k: u32) -> u32 {
        self.group_of.get(k as usize).copied().unwrap_or(0)
    }

    /// Group `g` and its ancestors, innermost first.
    pub fn ancestry(&self, g: u32) -> Vec<u32> {
        let mut out = vec![g];
        while let Some(p) = self.groups[*out.last().unwrap_or(&0) as usize].parent {
            out.push(p);
        }
        out
    }

    /// The world box of these objects (those with one).
    pub fn bounds_of(&self, objects: &[u32]) -> Option<([f64; 3], [f64; 3])> {
        objects
            .iter()
            .filter_map(|&k| self.bounds.get(k as usize).copied().flatten())
            .reduce(|(a0, a1), (b0, b1)| {
                (
                    std::array::from_fn(|i| a0[i].min(b0[i])),
                    std::array::from_fn(|i| a1[i].max(b1[i])),
                )
            })
    }

    /// The objects whose label, GlobalId or description (`table`'s text)
    /// holds `text`, ignoring case, in the tree's order; at most `limit`.
    pub fn search(&self, table: &ObjectTable, text: &str, limit: usize) -> Vec<u32> {
        let needle = text.trim().to_lowercase();
        if needle.is_empty() {
            return Vec::new();
        }
        self.order
            .iter()
            .copied()
            .filter(|&k| {
                self.label(k).to_lowercase().contains(&needle)
                    || self.global_id(k).to_lowercase().contains(&needle)
                    || table
                        .info(k)
                        .is_some_and(|t| t.to_lowercase().contains(&needle))
            })
            .take(limit)
            .collect()
    }

    /// The groups whose label is `text` (ignoring case and surrounding
    /// blanks), in the tree's order: a type is one group per storey.
    pub fn groups_named(&self, text: &str) -> Vec<u32> {
        let t = text.trim().to_lowercase();
        let mut out = Vec::new();
        let mut stack = vec![0u32];
        while let Some(g) = stack.pop() {
            let grp = &self.groups[g as usize];
            if grp.label.to_lowercase() == t {
                out.push(g);
            } else {
                stack.extend(grp.children.iter().rev());
            }
        }
        out
    }

    /// The objects of the groups named `text` ([`Self::groups_named`]), in
    /// the tree's order.
    pub fn objects_named(&self, text: &str) -> Vec<u32> {
        let mut out: Vec<u32> = (self.groups_named(text).iter())
            .flat_map(|&g| self.objects(g).iter().copied())
            .collect();
        out.dedup();
        out
    }

    /// How `objects` are drawn under `looks` (an object past its end is
    /// shown).
    pub fn counts(objects: &[u32], looks: &[Look]) -> Counts {
        let mut c = Counts::default();
        for &k in objects {
            match looks.get(k as usize).copied().unwrap_or_default() {
                Look::Shown => c.shown += 1,
                Look::Hidden => c.hidden += 1,
                Look::XRay => c.xray += 1,
            }
        }
        c
    }

    /// Applies `op` to `objects` in `looks` (grown to the tree's objects).
    pub fn apply(&self, looks: &mut Vec<Look>, objects: &[u32], op: Op) {
        looks.resize(self.order.len(), Look::Shown);
        let mut set = |l: Look| {
            for &k in objects {
                if let Some(x) = looks.get_mut(k as usize) {
                    *x = l;
                }
            }
        };
        match op {
            Op::Hide => set(Look::Hidden),
            Op::Show => set(Look::Shown),
            Op::XRay => set(Look::XRay),
            Op::Isolate => {
                looks.fill(Look::Hidden);
                self.apply(looks, objects, Op::Show);
            }
            Op::XRayOthers => {
                for l in looks.iter_mut().filter(|l| **l == Look::Shown) {
                    *l = Look::XRay;
                }
                self.apply(looks, objects, Op::Show);
            }
        }
    }

    /// Checks the hierarchy: every object once in the order; each group's
    /// objects its subgroups' ranges, one after another, then its direct
    /// ones; parents and children agree.
    pub fn validate(&self) -> Result<(), String> {
        let n = self.order.len();
        let mut seen = vec![false; n];
        for &k in &self.order {
            match seen.get_mut(k as usize) {
                Some(s) if !*s => *s = true,
                _ => return Err(format!("object {k} twice in the order, or out of range")),
            }
        }
        if self.groups.first().map(|g| g.objects.clone()) != Some(0..n as u32) {
            return Err("the model does not hold every object".into());
        }
        for (g, grp) in self.groups.iter().enumerate() {
            let mut at = grp.objects.start;
            for &c in &grp.children {
                let child = self
                    .groups
                    .get(c as usize)
                    .ok_or(format!("group {g}: child {c}?"))?;
                if child.parent != Some(g as u32) || child.objects.start != at {
                    return Err(format!("group {g}: child {c} out of place"));
                }
                at = child.objects.end;
            }
            if grp.direct != (at..grp.objects.end) {
                return Err(format!(
                    "group {g}: direct objects {:?} not the tail",
                    grp.direct
                ));
            }
            for &k in self.direct(g as u32) {
                if self.group_of(k) != g as u32 {
                    return Err(format!("object {k}: not in group {g}"));
                }
            }
        }
        Ok(())
    }
}

/// The first leaf that draws each object (a one-object leaf or chunk names
/// it, or a merged leaf's runs hold it), [`NONE`] for the objects the build
/// left out.
pub fn first_leaves(s: &crate::skeleton::Skeleton, table: &ObjectTable) -> Vec<u32> {
    let mut leaf = vec![NONE; table.len()];
    for (i, node) in s
        .nodes
        .iter()
        .enumerate()
        .filter(|(_, n)| n.child_count == 0)
    {
        let runs = table.runs_of(i as u32).iter().map(|r| r.object);
        for k in std::iter::once(node.object).chain(runs) {
            if let Some(l) = leaf.get_mut(k as usize).filter(|l| **l == NONE) {
                *l = i as u32;
            }
        }
    }
    leaf
}

/// Which objects some leaf draws ([`first_leaves`]); the others were left
/// out by the build.
pub fn drawn_objects(s: &crate::skeleton::Skeleton, table: &ObjectTable) -> Vec<bool> {
    first_leaves(s, table).iter().map(|&l| l != NONE).collect()
}

/// Each object's path of groups: the IFC spatial structure and type where
/// any object carries a site, building or storey; else its glTF parents
/// (less the ones every object shares), then its IFC type where any object
/// has one.
fn paths(described: &[Described]) -> Vec<Vec<Step>> {
    let any = |f: &dyn Fn(&Described) -> bool| described.iter().any(f);
    // What has no such group comes last.
    let step = |level, key, label: &str, none: &str| Step {
        level,
        key: if label.is_empty() { f64::INFINITY } else { key },
        label: if label.is_empty() { none } else { label }.to_string(),
    };
    let typed = any(&|d| !d.ifc_type.is_empty());
    if any(&|d| !d.site.is_empty() || !d.building.is_empty() || !d.storey.is_empty()) {
        let (site, building, storey) = (
            any(&|d| !d.site.is_empty()),
            any(&|d| !d.building.is_empty()),
            any(&|d| !d.storey.is_empty()),
        );
        return described
            .iter()
            .map(|d| {
                let mut p = Vec::with_capacity(4);
                if site {
                    p.push(step(Level::Site, 0.0, &d.site, "(no site)"));
                }
                if building {
                    p.push(step(Level::Building, 0.0, &d.building, "(no building)"));
                }
                if storey {
                    // Storeys bottom up; one without an elevation after.
                    let key = d.storey_elevation.unwrap_or(f64::MAX);
                    p.push(step(Level::Storey, key, &d.storey, "(no storey)"));
                }
                if typed {
                    p.push(step(Level::Type, 0.0, &d.ifc_type, "(no type)"));
                }
                p
            })
            .collect();
    }
    let shared = described.first().map_or(0, |first| {
        described.iter().fold(first.parents.len(), |c, d| {
            (first.parents[..c].iter().zip(&d.parents))
                .take_while(|(a, b)| a == b)
                .count()
        })
    });
    described
        .iter()
        .map(|d| {
            let mut p: Vec<Step> = (d.parents[shared.min(d.parents.len())..].iter())
                .map(|g| step(Level::Group, 0.0, g, "(unnamed)"))
                .collect();
            if typed {
                p.push(step(Level::Type, 0.0, &d.ifc_type, "(no type)"));
            }
            p
        })
        .collect()
}

#[cfg(test)]
mod tests;
