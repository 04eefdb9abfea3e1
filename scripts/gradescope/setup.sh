#!/usr/bin/env bash
# Gradescope autograder image set-up: Gradescope unpacks the autograder zip (this repository)
# into /autograder/source and runs this once while building the image.
set -euo pipefail
cd /autograder/source
bash scripts/setup.sh
