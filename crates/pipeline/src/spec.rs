//! The `[pipeline]` section of a config file: queue capacity and the ordered list of stages,
//! each a registry name plus its parameters.
//!
//! ```toml
//! [pipeline]
//! capacity = 8
//! [[pipeline.stages]]
//! stage = "detect.cog"
//! threshold = 40          # every other key is a parameter of that stage
//! ```
//!
//! Parameters stay a raw `toml::Table` here; each stage factory deserializes its own typed,
//! `deny_unknown_fields` parameter struct from it, so stages own their validation.

use serde::de::{self, Deserializer};
use serde::ser::{SerializeMap, Serializer};
use serde::{Deserialize, Serialize};

/// Queue capacity between two nodes when the config does not set one.
pub const DEFAULT_CAPACITY: usize = 8;

fn default_capacity() -> usize {
    DEFAULT_CAPACITY
}

fn positive_capacity<'de, D: Deserializer<'de>>(d: D) -> Result<usize, D::Error> {
    let n = usize::deserialize(d)?;
    if n == 0 {
        return Err(de::Error::custom(
            "pipeline capacity must be at least 1 (it is the size of each queue between stages)",
        ));
    }
    Ok(n)
}

/// Deserialize the stage list, prefixing an entry's error with its index: toml points errors
/// inside an array of tables at the array's first header, so the index is what locates it.
fn indexed_stages<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<StageSpec>, D::Error> {
    struct Stages;
    impl<'de> de::Visitor<'de> for Stages {
        type Value = Vec<StageSpec>;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("an array of [[pipeline.stages]] tables")
        }
        fn visit_seq<A: de::SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
            let mut stages = Vec::new();
            loop {
                let index = stages.len();
                match seq.next_element::<StageSpec>() {
                    Ok(Some(s)) => stages.push(s),
                    Ok(None) => return Ok(stages),
                    Err(e) => {
                        return Err(de::Error::custom(format!("pipeline.stages[{index}]: {e}")))
                    }
                }
            }
        }
    }
    d.deserialize_seq(Stages)
}

/// The `[pipeline]` table.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PipelineSpec {
    /// Size of each bounded queue between two nodes (≥ 1, default 8).
    #[serde(default = "default_capacity", deserialize_with = "positive_capacity")]
    pub capacity: usize,
    #[serde(deserialize_with = "indexed_stages")]
    pub stages: Vec<StageSpec>,
}

/// One `[[pipeline.stages]]` entry: `stage` names a registered stage; every other key is a
/// parameter passed to its factory.
#[derive(Debug, Clone, PartialEq)]
pub struct StageSpec {
    pub stage: String,
    pub params: toml::Table,
}

impl StageSpec {
    pub fn new(stage: impl Into<String>) -> Self {
        Self {
            stage: stage.into(),
            params: toml::Table::new(),
        }
    }

    /// Add a parameter (builder style).
    pub fn with(mut self, key: &str, value: impl Into<toml::Value>) -> Self {
        self.params.insert(key.to_owned(), value.into());
        self
    }
}

impl PipelineSpec {
    /// Parse the `[pipeline]` table of a whole config document, ignoring other tables.
    /// Errors carry the line and column.
    pub fn from_toml_str(document: &str) -> Result<Self, toml::de::Error> {
        #[derive(Deserialize)]
        struct Document {
            pipeline: PipelineSpec,
        }
        toml::from_str::<Document>(document).map(|d| d.pipeline)
    }
}

impl<'de> Deserialize<'de> for StageSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let mut params = toml::Table::deserialize(d)?;
        match params.remove("stage") {
            Some(toml::Value::String(stage)) => Ok(Self { stage, params }),
            Some(other) => Err(de::Error::custom(format!(
                "`stage` must be a string naming a registered stage, found {}",
                other.type_str()
            ))),
            None => Err(de::Error::custom(
                "missing field `stage` (every [[pipeline.stages]] entry needs `stage = \"<name>\"`)",
            )),
        }
    }
}

impl Serialize for StageSpec {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(Some(self.params.len() + 1))?;
        map.serialize_entry("stage", &self.stage)?;
        for (k, v) in &self.params {
            map.serialize_entry(k, v)?;
        }
        map.end()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DOC: &str = r#"
[camera]
device = "/dev/video0"

[pipeline]
capacity = 3

[[pipeline.stages]]
stage = "acquire"

[[pipeline.stages]]
stage = "detect.cog"
threshold = 40
window = 7.5
mode = "peak"
"#;

    #[test]
    fn parses_stages_and_params() {
        let s = PipelineSpec::from_toml_str(DOC).unwrap();
        assert_eq!(s.capacity, 3);
        assert_eq!(s.stages.len(), 2);
        assert_eq!(s.stages[0], StageSpec::new("acquire"));
        let cog = &s.stages[1];
        assert_eq!(cog.stage, "detect.cog");
        assert_eq!(cog.params.len(), 3);
        assert_eq!(cog.params["threshold"].as_integer(), Some(40));
        assert_eq!(cog.params["window"].as_float(), Some(7.5));
        assert_eq!(cog.params["mode"].as_str(), Some("peak"));
        assert!(!cog.params.contains_key("stage"));
    }

    #[test]
    fn capacity_defaults_to_eight() {
        let s = PipelineSpec::from_toml_str("[[pipeline.stages]]\nstage = \"a\"\n").unwrap();
        assert_eq!(s.capacity, DEFAULT_CAPACITY);
        assert_eq!(DEFAULT_CAPACITY, 8);
    }

    #[test]
    fn missing_stage_is_rejected_with_its_line() {
        let doc =
            "[pipeline]\n[[pipeline.stages]]\nstage = \"a\"\n[[pipeline.stages]]\nthreshold = 4\n";
        let err = PipelineSpec::from_toml_str(doc).unwrap_err().to_string();
        assert!(
            err.contains("pipeline.stages[1]: missing field `stage`"),
            "{err}"
        );
        assert!(err.contains("line "), "{err}");
    }

    #[test]
    fn stage_must_be_a_string() {
        let err = PipelineSpec::from_toml_str("[[pipeline.stages]]\nstage = 3\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("pipeline.stages[0]: `stage` must be a string"),
            "{err}"
        );
    }

    #[test]
    fn zero_capacity_and_unknown_keys_are_rejected() {
        let err = PipelineSpec::from_toml_str("[pipeline]\ncapacity = 0\nstages = []\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("at least 1") && err.contains("line 2"),
            "{err}"
        );
        let err = PipelineSpec::from_toml_str("[pipeline]\ncapcity = 2\nstages = []\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("unknown field `capcity`"), "{err}");
    }

    #[test]
    fn serializes_back_to_the_same_spec() {
        let s = PipelineSpec::from_toml_str(DOC).unwrap();
        let text = toml::to_string(&toml::Table::from_iter([(
            "pipeline".to_owned(),
            toml::Value::try_from(&s).unwrap(),
        )]))
        .unwrap();
        assert_eq!(PipelineSpec::from_toml_str(&text).unwrap(), s);
    }
}
