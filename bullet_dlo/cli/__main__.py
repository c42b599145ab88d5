"""``python -m bullet_dlo.cli`` runs the command line."""
import sys

from bullet_dlo.cli.main import main

sys.exit(main())
