#!/usr/bin/env bash
# The Python module's tests (python/tests, pytest): builds the module into a virtual
# environment with the tests' profile, as the README's install line does with the release
# profile, and runs them against the command line's binary of the same profile.
#
#   scripts/test-python.sh            # after `cargo test --profile ci --workspace` (CI)
#   scripts/test-python.sh -k merge   # pytest's arguments pass through
#
# Environment:
#   LIGHTSPLIT_TEST_PROFILE=P  the cargo profile of the module and the binary (default ci)
#   LIGHTSPLIT_PY_VENV=DIR     the virtual environment (default target/python-venv, made when
#                              missing; pip installs maturin, numpy, pytest and openexr there)
#   PYTHON=BIN                 the Python that makes it (default python3)
# The module builds without build isolation: maturin is already in the venv, and an isolated
# build would install it a second time.
# Exit status: pytest's (0 when every test passed), 1 when the build fails.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
profile=${LIGHTSPLIT_TEST_PROFILE:-ci}
venv=${LIGHTSPLIT_PY_VENV:-target/python-venv}
python=${PYTHON:-python3}

if [ ! -x "$venv/bin/python" ]; then
    echo "test-python: making $venv"
    "$python" -m venv "$venv"
fi
venv_bin=$(cd "$venv/bin" && pwd)
"$venv/bin/python" -m pip install -q --disable-pip-version-check "maturin>=1.9.4,<2" numpy pytest "openexr>=3.2"
cargo build -q --profile "$profile" --bin lightsplit
echo "test-python: building the module (profile $profile)"
PATH="$venv_bin:$PATH" MATURIN_PEP517_ARGS="--profile $profile" "$venv/bin/python" -m pip install -q --disable-pip-version-check \
    --force-reinstall --no-deps --no-build-isolation ./python
LIGHTSPLIT="$root/target/$profile/lightsplit" "$venv/bin/python" -m pytest -q -p no:cacheprovider python/tests "$@"
