//! The link/joint tree of a URDF and the serial path between two links.

use std::collections::HashMap;

use urdf_rs::Robot;

use crate::UrdfImportError;

/// One joint of a path between two links: traversed from parent to child (down the tree) or,
/// `reversed`, from child to parent (up the tree).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct PathJoint {
    /// index into `robot.joints`
    pub joint: usize,
    /// true when the path goes from the joint's child link to its parent link
    pub reversed: bool,
}

/// Parent/child maps over a parsed URDF (indices into `robot.joints`).
#[derive(Debug)]
pub(crate) struct Tree<'a> {
    /// the parsed robot
    pub robot: &'a Robot,
    /// link name → index of the joint whose child it is
    pub parent_joint: HashMap<&'a str, usize>,
    /// link name → indices of the joints whose parent it is (file order)
    pub child_joints: HashMap<&'a str, Vec<usize>>,
    /// link name → index into `robot.links`
    pub link_index: HashMap<&'a str, usize>,
}

impl<'a> Tree<'a> {
    /// Builds the maps; a joint naming an unknown link or a link with two parent joints is an
    /// error (the file is then not a tree).
    pub fn new(robot: &'a Robot, origin: &str) -> Result<Self, UrdfImportError> {
        let mut link_index = HashMap::new();
        for (k, l) in robot.links.iter().enumerate() {
            if link_index.insert(l.name.as_str(), k).is_some() {
                return Err(UrdfImportError::InvalidTree {
                    origin: origin.to_string(),
                    reason: format!("link `{}` is defined twice", l.name),
                });
            }
        }
        let mut parent_joint: HashMap<&str, usize> = HashMap::new();
        let mut child_joints: HashMap<&str, Vec<usize>> = HashMap::new();
        for (k, j) in robot.joints.iter().enumerate() {
            for (role, link) in [("parent", &j.parent.link), ("child", &j.child.link)] {
                if !link_index.contains_key(link.as_str()) {
                    return Err(UrdfImportError::InvalidTree {
                        origin: origin.to_string(),
                        reason: format!(
                            "joint `{}` names {role} link `{link}`, which is not defined",
                            j.name
                        ),
                    });
                }
            }
            if let Some(&other) = parent_joint.get(j.child.link.as_str()) {
                return Err(UrdfImportError::InvalidTree {
                    origin: origin.to_string(),
                    reason: format!(
                        "link `{}` is the child of two joints (`{}` and `{}`); a URDF must be a tree",
                        j.child.link, robot.joints[other].name, j.name
                    ),
                });
            }
            parent_joint.insert(j.child.link.as_str(), k);
            child_joints.entry(j.parent.link.as_str()).or_default().push(k);
        }
        Ok(Self { robot, parent_joint, child_joints, link_index })
    }

    /// Names of all links, for error messages (at most 20, then "...").
    pub fn link_list(&self) -> String {
        let names: Vec<&str> = self.robot.links.iter().map(|l| l.name.as_str()).collect();
        if names.len() > 20 { format!("{}, ...", names[..20].join(", ")) } else { names.join(", ") }
    }

    /// Ancestor joints of `link`, nearest first (stops at the root). Errors on a loop.
    pub fn ancestors(&self, link: &str, origin: &str) -> Result<Vec<usize>, UrdfImportError> {
        let mut out = Vec::new();
        let mut current = link;
        while let Some(&j) = self.parent_joint.get(current) {
            if out.len() > self.robot.joints.len() {
                return Err(UrdfImportError::InvalidTree {
                    origin: origin.to_string(),
                    reason: format!("the joints above link `{link}` form a loop"),
                });
            }
            out.push(j);
            current = self.robot.joints[j].parent.link.as_str();
        }
        Ok(out)
    }

    /// The serial path between two links of the tree, in order from `base`: up from `base` to
    /// the lowest common ancestor of the two links (those joints traversed from child to parent,
    /// `reversed`), then down to `tip`. Unknown links, `base == tip` and links in two separate
    /// trees are errors.
    pub fn path(&self, base: &str, tip: &str, origin: &str) -> Result<Vec<PathJoint>, UrdfImportError> {
        for (role, link) in [("base", base), ("tip", tip)] {
            if !self.link_index.contains_key(link) {
                return Err(UrdfImportError::UnknownLink {
                    origin: origin.to_string(),
                    role,
                    link: link.to_string(),
                    known: self.link_list(),
                });
            }
        }
        let no_path = |reason: String| UrdfImportError::NoPath {
            origin: origin.to_string(),
            base: base.to_string(),
            tip: tip.to_string(),
            reason,
        };
        if base == tip {
            return Err(no_path("the base and tip links are the same link".into()));
        }
        self.path_between(base, tip, origin)?.ok_or_else(|| {
            let root = |l: &str| -> String {
                self.ancestors(l, origin)
                    .ok()
                    .and_then(|up| up.last().map(|&j| self.robot.joints[j].parent.link.clone()))
                    .unwrap_or_else(|| l.to_string())
            };
            no_path(format!("they are in two separate trees (roots `{}` and `{}`)", root(base), root(tip)))
        })
    }

    /// The path from link `from` to link `to` (both known; empty when equal), or `None` when
    /// they are not connected.
    pub fn path_between(
        &self,
        from: &str,
        to: &str,
        origin: &str,
    ) -> Result<Option<Vec<PathJoint>>, UrdfImportError> {
        let up_from = self.ancestors(from, origin)?;
        let up_to = self.ancestors(to, origin)?;
        // links above `from` (itself first) and how many joints up each one is
        let mut depth_from: HashMap<&str, usize> = HashMap::new();
        depth_from.insert(from, 0);
        for (k, &j) in up_from.iter().enumerate() {
            depth_from.insert(self.robot.joints[j].parent.link.as_str(), k + 1);
        }
        // the first link above (or at) `to` that is also above (or at) `from`: the lowest
        // common ancestor
        let mut down = Vec::new();
        let mut lca_depth = depth_from.get(to).copied();
        if lca_depth.is_none() {
            for &j in &up_to {
                down.push(j);
                if let Some(&d) = depth_from.get(self.robot.joints[j].parent.link.as_str()) {
                    lca_depth = Some(d);
                    break;
                }
            }
        }
        let Some(up_count) = lca_depth else { return Ok(None) };
        let mut path: Vec<PathJoint> =
            up_from[..up_count].iter().map(|&joint| PathJoint { joint, reversed: true }).collect();
        path.extend(down.iter().rev().map(|&joint| PathJoint { joint, reversed: false }));
        Ok(Some(path))
    }

    /// The links of the subtree rooted at `root` (root first, depth-first, file order).
    pub fn subtree(&self, root: &'a str) -> Vec<&'a str> {
        let mut out = Vec::new();
        let mut stack = vec![root];
        while let Some(l) = stack.pop() {
            if out.len() > self.robot.links.len() {
                break; // a loop (impossible after `new` accepted the file) must not hang
            }
            out.push(l);
            if let Some(js) = self.child_joints.get(l) {
                for &j in js.iter().rev() {
                    stack.push(self.robot.joints[j].child.link.as_str());
                }
            }
        }
        out
    }
}

/// 1-based line of the `<tag ... name="name" ...>` element in `text`, if found.
pub(crate) fn element_line(text: &str, tag: &str, name: &str) -> Option<usize> {
    let open = format!("<{tag}");
    let mut from = 0;
    while let Some(rel) = text[from..].find(&open) {
        let start = from + rel;
        let after = start + open.len();
        from = after;
        // the tag name must end here (`<joint` but not `<jointx`)
        if !text[after..].starts_with(|c: char| c.is_whitespace()) {
            continue;
        }
        let end = text[after..].find('>').map_or(text.len(), |e| after + e);
        let head = &text[after..end];
        if head.contains(&format!("name=\"{name}\"")) || head.contains(&format!("name='{name}'")) {
            return Some(text[..start].matches('\n').count() + 1);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn element_line_finds_the_tag() {
        let t = "<robot>\n <link name=\"a\"/>\n <joint\n   name='j1' type=\"fixed\">\n</joint>\n<jointx name=\"j2\"/>";
        assert_eq!(element_line(t, "joint", "j1"), Some(3));
        assert_eq!(element_line(t, "link", "a"), Some(2));
        assert_eq!(element_line(t, "joint", "j2"), None);
    }
}
