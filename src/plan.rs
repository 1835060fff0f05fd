//! `splatbench plan`: a method's tree shape for a number of points, without data.

use anyhow::bail;
use clap::Args;
use methods::MethodKind;

#[derive(Args, Clone)]
pub struct PlanArgs {
    /// Method (`mwkd`, or a registered one).
    #[arg(long)]
    pub method: Option<String>,
    /// Number of input points (digits, `_` separators, k/M/G suffix).
    #[arg(long)]
    pub points: Option<String>,
    /// Method parameter, `key=value` (repeatable), e.g. fanout=6, vbo=4009.
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,
    /// Print JSON instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// `splatbench plan`: the table (or JSON) of [`methods::mwkd::tree::Plan`].
pub fn main(a: &PlanArgs) -> anyhow::Result<()> {
    use methods::mwkd;
    let Some(name) = a.method.as_deref() else {
        bail!("--method is required (e.g. --method {})", mwkd::NAME);
    };
    if name != mwkd::NAME {
        match name.parse::<MethodKind>() {
            Ok(kind) => bail!(
                "method '{kind}' cannot plan without data: its structure depends on the sample \
                 positions (build it with `splatbench build --method {kind}`); `plan` answers \
                 for: {}",
                mwkd::NAME
            ),
            Err(e) => bail!("--method: {e}"),
        }
    }
    let Some(points) = a.points.as_deref() else {
        bail!("--points is required (the number of input samples, e.g. --points 186850683)");
    };
    let n = scenes::spec::parse_count(points).map_err(|e| anyhow::anyhow!("--points: {e}"))?;
    let params = crate::args::method_params(MethodKind::Mwkd, &a.params)?;
    let p = mwkd::MwkdParams::from_params(&params)?;
    if p.tree == mwkd::TreeKind::Octree {
        bail!(
            "--param tree=octree: an octree's shape depends on the data; only tree=mwkd and tree=kd can be planned"
        );
    }
    anyhow::ensure!(
        n >= 1,
        "--points {points}: the tree needs at least 1 sample"
    );
    let plan = mwkd::tree::Plan::new(n as u64, u64::from(p.effective_fanout()), p.vbo)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&plan.to_json())?);
    } else {
        print!("{}", plan.table());
    }
    Ok(())
}
