from csim.cli import main

main()
