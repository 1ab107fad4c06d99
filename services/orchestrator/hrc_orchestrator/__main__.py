from hrc_orchestrator.main import main

raise SystemExit(main())
