//! Batches past one machine: `bake --shard K/N` bakes shard K of N, a
//! deterministic 1/N of a batch's levels, so that N machines (a CI matrix,
//! a Slurm array job, GNU parallel over ssh) together bake every level once.
//!
//! **The rule.** A level belongs to shard `1 + h mod N`, where `h` is the
//! first 8 bytes, read as a little-endian `u64`, of the blake3 hash of the
//! level's name: its image's file stem, the name its outputs are written
//! under (`levels/cave.png` is `cave`). So a level's shard depends only on
//! its name and N: not on the machine, the folder it was given as, the
//! current directory, the thread count or which other levels exist. Adding a
//! level never moves another one to a different shard. Two images with the
//! same name (`a/room.png`, `b/room.bmp`) land in the same shard, where the
//! batch refuses the second as a name clash, as it would without shards.
//! The price of hashing is balance: with few levels the shards can differ
//! in size (an empty shard is fine: it bakes nothing and says so).

use std::fmt;
use std::str::FromStr;

/// Shard `index` of `count` (both from 1, `index <= count`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct Shard {
    /// Which shard, 1 to `count`.
    pub index: u32,
    /// How many shards the batch is cut into, at least 1.
    pub count: u32,
}

/// Why a `K/N` shard cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ShardError {
    /// Not two whole numbers separated by `/`.
    #[error("a shard is K/N, two whole numbers such as 2/3 (shard 2 of 3), not {0:?}")]
    Syntax(String),
    /// N is 0.
    #[error("a shard is K/N with N at least 1 (the number of shards), not {0:?}")]
    NoShards(String),
    /// K is 0 or larger than N.
    #[error(
        "a shard is K/N with K from 1 to N (shards count from 1), not {text:?}: K is 1 to {count}"
    )]
    OutOfRange {
        /// What was given.
        text: String,
        /// N.
        count: u32,
    },
}

impl Shard {
    /// Shard `index` of `count`, checked.
    pub fn new(index: u32, count: u32) -> Result<Shard, ShardError> {
        let text = format!("{index}/{count}");
        if count == 0 {
            return Err(ShardError::NoShards(text));
        }
        if index == 0 || index > count {
            return Err(ShardError::OutOfRange { text, count });
        }
        Ok(Shard { index, count })
    }

    /// The shard (1 to `count`) that the level named `name` belongs to.
    pub fn of_name(name: &str, count: u32) -> u32 {
        let hash = blake3::hash(name.as_bytes());
        let mut first = [0u8; 8];
        first.copy_from_slice(&hash.as_bytes()[..8]);
        let h = u64::from_le_bytes(first);
        // `count` is at least 1 for every checked shard; 0 is treated as 1.
        1 + (h % u64::from(count.max(1))) as u32
    }

    /// True when the level named `name` is in this shard.
    pub fn holds(&self, name: &str) -> bool {
        Shard::of_name(name, self.count) == self.index
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = ShardError;

    fn from_str(s: &str) -> Result<Shard, ShardError> {
        let syntax = || ShardError::Syntax(s.to_string());
        let (k, n) = s.trim().split_once('/').ok_or_else(syntax)?;
        let whole = |t: &str| {
            let t = t.trim();
            if t.is_empty() || !t.bytes().all(|b| b.is_ascii_digit()) {
                return Err(syntax());
            }
            t.parse::<u32>().map_err(|_| syntax())
        };
        let (k, n) = (whole(k)?, whole(n)?);
        Shard::new(k, n).map_err(|e| match e {
            ShardError::NoShards(_) => ShardError::NoShards(s.to_string()),
            ShardError::OutOfRange { count, .. } => ShardError::OutOfRange {
                text: s.to_string(),
                count,
            },
            other => other,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_k_of_n_and_refuses_the_rest_with_the_reason() {
        assert_eq!("2/3".parse(), Ok(Shard { index: 2, count: 3 }));
        assert_eq!("1/1".parse(), Ok(Shard { index: 1, count: 1 }));
        assert!(matches!(
            "0/3".parse::<Shard>(),
            Err(ShardError::OutOfRange { count: 3, .. })
        ));
        assert!(matches!(
            "4/3".parse::<Shard>(),
            Err(ShardError::OutOfRange { count: 3, .. })
        ));
        assert!(matches!(
            "1/0".parse::<Shard>(),
            Err(ShardError::NoShards(_))
        ));
        for bad in ["a/b", "2", "2/", "/3", "-1/3", "2/3/4", "+1/3", "1.5/3", ""] {
            assert!(
                matches!(bad.parse::<Shard>(), Err(ShardError::Syntax(_))),
                "{bad:?}"
            );
        }
    }

    #[test]
    fn every_name_is_in_exactly_one_shard() {
        for count in 1..=7 {
            for i in 0..200 {
                let name = format!("level_{i}");
                let holding: Vec<u32> = (1..=count)
                    .filter(|&k| Shard::new(k, count).unwrap().holds(&name))
                    .collect();
                assert_eq!(holding.len(), 1, "{name} in {holding:?} of {count}");
            }
        }
    }

    /// The documented rule, spelled out independently: blake3 of the name,
    /// its first 8 bytes little-endian, modulo N, plus 1. Machines running
    /// different builds must agree on it.
    #[test]
    fn the_shard_of_a_name_is_the_documented_hash_rule() {
        for name in ["cornell", "dungeon", "big_level", "a", ""] {
            let bytes = *blake3::hash(name.as_bytes()).as_bytes();
            let h = bytes[..8]
                .iter()
                .rev()
                .fold(0u64, |acc, &b| (acc << 8) | u64::from(b));
            for n in [1u32, 2, 3, 10] {
                assert_eq!(Shard::of_name(name, n), 1 + (h % u64::from(n)) as u32);
            }
        }
    }
}
