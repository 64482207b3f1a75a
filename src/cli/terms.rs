//! `nsrm terms`: prints a model's term list.

use super::common::UsageError;
use super::values;
use crate::model::{term_name, terms, Kind};
use anyhow::Result;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    kind: values::KindArg,
    /// Order, 1..4.
    #[arg(long, default_value_t = 3)]
    order: u8,
}

pub(crate) fn run(a: Args) -> Result<ExitCode> {
    let kind = Kind::from(a.kind.kind);
    if !(1..=4).contains(&a.order) {
        return Err(UsageError(format!("--order {} is out of range (1..4)", a.order)).into());
    }
    let order = kind.effective_order(a.order);
    let t = terms(kind, order);
    println!("{kind} order {order}: {} terms", t.len());
    for (i, term) in t.iter().enumerate() {
        println!("{i:3}  {}", term_name(kind, term));
    }
    Ok(ExitCode::SUCCESS)
}
