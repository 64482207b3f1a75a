//! Plots (placeholder until the plot module lands).
