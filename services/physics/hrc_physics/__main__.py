from hrc_physics.main import main

raise SystemExit(main())
