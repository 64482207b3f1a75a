//! dctl
