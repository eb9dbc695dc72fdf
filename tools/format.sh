#!/usr/bin/env bash
# Applies .clang-format to every C++ file of the repo.
set -euo pipefail
cd "$(dirname "$0")/.."
git ls-files -co --exclude-standard '*.h' '*.cpp' | xargs -r clang-format -i
