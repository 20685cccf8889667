//! The stage registry: maps a stage name from the config ("acquire", "detect.cog",
//! "sink.ply", ...) to a factory that builds the node from its TOML parameters.
//!
//! This is what lets a config file swap a detector or add a sink without touching the runner.
//! The context `C` carries whatever factories need besides their parameters (calibration, the
//! camera handle, output directory, ...).

use std::collections::BTreeMap;

use super::error::{BoxError, BuildError};
use super::node::Node;
use super::runner::Pipeline;
use super::spec::PipelineSpec;

/// Builds a node from its parameters (every key of its `[[pipeline.stages]]` table except
/// `stage`) and the shared context.
pub type Factory<T, C> = dyn Fn(&toml::Table, &C) -> Result<Node<T>, BoxError> + Send + Sync;

struct Entry<T, C> {
    description: String,
    factory: Box<Factory<T, C>>,
}

/// Named stage factories for item type `T` and factory context `C`.
pub struct Registry<T, C> {
    entries: BTreeMap<String, Entry<T, C>>,
}

impl<T, C> Default for Registry<T, C> {
    fn default() -> Self {
        Self {
            entries: BTreeMap::new(),
        }
    }
}

impl<T, C> std::fmt::Debug for Registry<T, C> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_map().entries(self.entries()).finish()
    }
}

impl<T, C> Registry<T, C> {
    pub fn new() -> Self {
        Self::default()
    }

    /// Register `factory` under `name` with a one-line `description`.
    ///
    /// # Panics
    /// If `name` is already registered (a programming error, caught by any test that builds
    /// the registry).
    pub fn register<F>(&mut self, name: &str, description: &str, factory: F) -> &mut Self
    where
        F: Fn(&toml::Table, &C) -> Result<Node<T>, BoxError> + Send + Sync + 'static,
    {
        let entry = Entry {
            description: description.to_owned(),
            factory: Box::new(factory),
        };
        if self.entries.insert(name.to_owned(), entry).is_some() {
            panic!("pipeline stage `{name}` registered twice");
        }
        self
    }

    /// Registered names, sorted.
    pub fn names(&self) -> Vec<&str> {
        self.entries.keys().map(String::as_str).collect()
    }

    /// `(name, description)` pairs, sorted by name (for `footscan stages`-style listings).
    pub fn entries(&self) -> impl Iterator<Item = (&str, &str)> {
        self.entries
            .iter()
            .map(|(n, e)| (n.as_str(), e.description.as_str()))
    }

    pub fn description(&self, name: &str) -> Option<&str> {
        self.entries.get(name).map(|e| e.description.as_str())
    }

    pub fn contains(&self, name: &str) -> bool {
        self.entries.contains_key(name)
    }
}

impl<T: Send + 'static, C> Registry<T, C> {
    /// Build every node of `spec` in order and check the chain shape.
    ///
    /// All names are checked before any factory runs (factories may open devices or files).
    pub fn build(&self, spec: &PipelineSpec, ctx: &C) -> Result<Pipeline<T>, BuildError> {
        if spec.capacity == 0 {
            return Err(BuildError::Capacity(spec.capacity));
        }
        if let Some((index, s)) = spec
            .stages
            .iter()
            .enumerate()
            .find(|(_, s)| !self.contains(&s.stage))
        {
            return Err(BuildError::UnknownStage {
                index,
                name: s.stage.clone(),
                valid: self.names().into_iter().map(str::to_owned).collect(),
            });
        }
        let mut nodes = Vec::with_capacity(spec.stages.len());
        for (index, s) in spec.stages.iter().enumerate() {
            let entry = &self.entries[&s.stage];
            let node = (entry.factory)(&s.params, ctx).map_err(|source| BuildError::Factory {
                index,
                stage: s.stage.clone(),
                source,
            })?;
            nodes.push((s.stage.clone(), node));
        }
        Pipeline::new(spec.capacity, nodes)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Arc;

    use super::*;
    use crate::{Emitter, FnSource, FnStage, StageSpec};

    /// Context: a value added by `add` stages.
    struct Ctx {
        offset: u64,
    }

    fn registry(built: Arc<AtomicUsize>) -> Registry<u64, Ctx> {
        let mut r = Registry::new();
        let b = built.clone();
        r.register("count", "emits 0..n", move |p, _ctx: &Ctx| {
            b.fetch_add(1, Ordering::SeqCst);
            let n = p
                .get("n")
                .and_then(toml::Value::as_integer)
                .ok_or("`n` (integer) is required")?;
            let n = u64::try_from(n).map_err(|_| "`n` must be ≥ 0")?;
            Ok(Node::source(FnSource(move |out: &mut Emitter<u64>| {
                for i in 0..n {
                    out.emit(i)?;
                }
                Ok(())
            })))
        });
        r.register("add", "adds the context offset", move |_, ctx: &Ctx| {
            built.fetch_add(1, Ordering::SeqCst);
            let k = ctx.offset;
            Ok(Node::stage(FnStage(
                move |x: u64, out: &mut Emitter<u64>| {
                    out.emit(x + k)?;
                    Ok(())
                },
            )))
        });
        r
    }

    fn spec(stages: Vec<StageSpec>) -> PipelineSpec {
        PipelineSpec {
            capacity: 4,
            stages,
        }
    }

    #[test]
    fn names_are_sorted_with_descriptions() {
        let r = registry(Arc::default());
        assert_eq!(r.names(), vec!["add", "count"]);
        assert_eq!(r.description("add"), Some("adds the context offset"));
        assert_eq!(r.entries().next(), Some(("add", "adds the context offset")));
        assert!(!r.contains("sink.ply"));
    }

    #[test]
    fn builds_and_runs_from_a_spec_with_params_and_context() {
        let r = registry(Arc::default());
        let s = PipelineSpec::from_toml_str(
            "[pipeline]\ncapacity = 2\n[[pipeline.stages]]\nstage = \"count\"\nn = 4\n\
             [[pipeline.stages]]\nstage = \"add\"\n",
        )
        .unwrap();
        let p = r.build(&s, &Ctx { offset: 10 }).unwrap();
        assert_eq!(p.names(), vec!["count", "add"]);
        assert_eq!(p.capacity(), 2);
        let report = p.start().wait().unwrap();
        assert_eq!(report.outputs, vec![10, 11, 12, 13]);
    }

    #[test]
    fn unknown_stage_lists_valid_names_before_any_factory_runs() {
        let built = Arc::new(AtomicUsize::new(0));
        let r = registry(built.clone());
        let s = spec(vec![
            StageSpec::new("count").with("n", 3),
            StageSpec::new("detect.cgo"),
        ]);
        let err = r.build(&s, &Ctx { offset: 0 }).unwrap_err();
        assert_eq!(
            err.to_string(),
            "pipeline.stages[1]: unknown stage `detect.cgo`; valid stages: add, count"
        );
        assert_eq!(built.load(Ordering::SeqCst), 0);
    }

    /// The error and its causes, `outer: cause`, as the edges print them.
    fn chain(e: &dyn std::error::Error) -> String {
        let mut s = e.to_string();
        let mut c = e.source();
        while let Some(x) = c {
            s = format!("{s}: {x}");
            c = x.source();
        }
        s
    }

    #[test]
    fn factory_errors_name_the_stage() {
        let r = registry(Arc::default());
        let err = r
            .build(&spec(vec![StageSpec::new("count")]), &Ctx { offset: 0 })
            .unwrap_err();
        assert!(matches!(err, BuildError::Factory { index: 0, ref stage, .. } if stage == "count"));
        assert_eq!(
            chain(&err),
            "pipeline.stages[0] `count`: `n` (integer) is required"
        );
    }

    #[test]
    fn second_source_is_rejected() {
        let r = registry(Arc::default());
        let s = spec(vec![
            StageSpec::new("count").with("n", 1),
            StageSpec::new("add"),
            StageSpec::new("count").with("n", 1),
        ]);
        let err = r.build(&s, &Ctx { offset: 0 }).unwrap_err();
        assert_eq!(
            err.to_string(),
            "pipeline.stages[2] `count` is a source; only the first stage may be a source"
        );
    }

    #[test]
    fn first_stage_must_be_a_source() {
        let r = registry(Arc::default());
        let err = r
            .build(&spec(vec![StageSpec::new("add")]), &Ctx { offset: 0 })
            .unwrap_err();
        assert!(matches!(err, BuildError::FirstNotSource { ref stage } if stage == "add"));
        let err = r.build(&spec(vec![]), &Ctx { offset: 0 }).unwrap_err();
        assert!(matches!(err, BuildError::Empty));
    }

    #[test]
    #[should_panic(expected = "registered twice")]
    fn duplicate_registration_panics() {
        let mut r = registry(Arc::default());
        r.register("add", "again", |_, _| Err("unused".into()));
    }
}
