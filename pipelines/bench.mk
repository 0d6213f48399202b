bench:
	@echo todo
