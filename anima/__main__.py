from anima.cli.main import run

run()
