#!/bin/sh
# The farm engines the farm tests run for real: Open Job Description's CLI (`openjd check` /
# `openjd run`, the job format of AWS Deadline Cloud) and a single-node Slurm (slurmctld, slurmd,
# the client commands and munge); PyPI `deadline` (the Deadline Cloud client), whose job-bundle
# reader judges the Open Job Description bundles; PyPI `kubernetes-validate`, which checks the
# Kubernetes manifests against the API's JSON schemas it ships (offline, per Kubernetes version).
# Installs only what is missing.
set -eu
if ! command -v openjd >/dev/null 2>&1; then
    pip install -q openjd-cli || pip install -q --break-system-packages openjd-cli
fi
if ! python3 -c "import deadline.client.job_bundle" >/dev/null 2>&1; then
    pip install -q deadline || pip install -q --break-system-packages deadline
fi
if ! command -v kubernetes-validate >/dev/null 2>&1; then
    pip install -q kubernetes-validate || pip install -q --break-system-packages kubernetes-validate
fi
missing=""
for c in slurmctld:slurmctld slurmd:slurmd sbatch:slurm-client munged:munge; do
    command -v "${c%%:*}" >/dev/null 2>&1 || missing="$missing ${c#*:}"
done
if [ -n "$missing" ]; then
    apt-get update -qq
    # shellcheck disable=SC2086
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $missing >/dev/null
fi
python3 -c "import deadline.client.job_bundle" && command -v openjd >/dev/null && command -v kubernetes-validate >/dev/null && command -v slurmctld >/dev/null && command -v slurmd >/dev/null \
    && command -v sbatch >/dev/null && command -v munged >/dev/null
