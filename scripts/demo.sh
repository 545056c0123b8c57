#!/usr/bin/env bash
# The main job: the specification's annex session, run by the asserv command.
. "$(dirname "$0")/setup.sh" demo
exec asserv demo "$@"
