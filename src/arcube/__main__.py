"""python -m arcube"""

from arcube.cli import main

main()
