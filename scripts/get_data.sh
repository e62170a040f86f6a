#!/usr/bin/env bash
# The evaluation scans (SemanticKITTI seq00 frames, ISPRS tiles, RELLIS-3D frame, airborne tiles,
# two unlabelled scans) from their public sources, pinned in scripts/data_manifest.tsv (URL at a
# commit, SHA-256, licence), converted where the source is another format, each checked against
# the manifest. A file is renamed into place only once its checksum matches: a failed or
# interrupted run leaves no half-written file; a second run fetches only what is missing.
#
#   bash scripts/get_data.sh                 # download into $GF_DATA_DIR, else <repo>/data
#   bash scripts/get_data.sh --dest DIR      # into DIR (created if missing)
#   bash scripts/get_data.sh --from COPY     # copy from an offline copy of the data folder
#   bash scripts/get_data.sh --check         # check the data folder against the manifest
#   bash scripts/get_data.sh --list          # files, sources, licences
#   bash scripts/get_data.sh --held-out      # the held-out scans (heldout_manifest.tsv) into
#                                            # <data folder>/heldout (any option above applies;
#                                            # with --dest DIR into DIR itself: give it
#                                            # <data folder>/heldout for scripts/eval_all.sh)
#
# Environment: GF_DATA_DIR (data folder; must exist), GF_DATA_BASE_URL (replaces
# https://raw.githubusercontent.com/ in every source URL: a mirror, or file:///DIR/ with the files
# at DIR/<owner>/<repo>/<commit>/<path>), GF_DATA_MANIFEST (another
# manifest, for the tests).
# Needs python3 (and python3-numpy for the converted files). The two airborne tiles come as LAZ:
# converting them needs laspy with a LAZ backend (pip install 'laspy[lazrs]') or PDAL's `pdal`,
# which Debian 12 does not package; without one they are reported as not made (exit 1) and
# `--from` a copy gives them.
# Exit status: 0 every file present with its checksum; 1 some file not made (each named, with
# the reason); 2 bad arguments.
set -euo pipefail
export PATH="/usr/bin:/bin:${PATH}"
exec python3 "$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/get_data.py" "$@"
