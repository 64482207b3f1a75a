//! `nsrm terms`: prints a model's term list.

use super::common::UsageError;
use super::values;
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
    let kind = a.kind.kind;
    if !(1..=4).contains(&a.order) {
        return Err(UsageError(format!("--order {} is out of range (1..4)", a.order)).into());
    }
    let order = kind.effective_order(a.order);
    let names = kind.term_names(order);
    println!("{kind} order {order}: {} terms", names.len());
    for (i, name) in names.iter().enumerate() {
        println!("{i:3}  {name}");
    }
    Ok(ExitCode::SUCCESS)
}
