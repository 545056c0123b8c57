#!/usr/bin/env bash
# The main job: the specification's annex session, run by the asserv command. The set-up
# installs once (scripts/setup.sh skips pip when nothing it builds from has changed); the plot
# is written in the folder this is run from, and the demo prints its absolute path.
HERE=$PWD
. "$(dirname "$0")/setup.sh" demo
cd "$HERE"
exec asserv demo "$@"
