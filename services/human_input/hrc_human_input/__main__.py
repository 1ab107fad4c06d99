from hrc_human_input.main import main

raise SystemExit(main())
