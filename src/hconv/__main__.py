from hconv.cli import main

main()
